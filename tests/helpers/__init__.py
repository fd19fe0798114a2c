"""Modules shared by the tests, the benchmarks and the studies: synthetic scenes and problems, independent
oracles, bad inputs, and the scripts the desktop and subprocess tests run."""
