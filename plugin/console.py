"""The console qgis_process writes a step's lines to.

qgis_process prints the feedback's lines (pushInfo, pushWarning) through C's stdout. Where that is a pipe or a
file (a script's log, a batch system), C buffers it in blocks of 4 KB: the lines of a long step then reach the
log minutes late, all at once at its end. `line_buffered_stdout` makes C's stdout line-buffered, so each line
leaves as it is written; once per process (the stream keeps its mode). glibc's setvbuf with no buffer of ours
only sets the stream's mode (a call after output is safe there); where the program's symbols have no C `stdout`
nothing changes."""

import ctypes
import functools

_IOLBF = 1  # glibc's <stdio.h>


@functools.cache
def line_buffered_stdout() -> bool:
    """Make C's stdout line-buffered (module docstring); whether it was done."""
    try:
        libc = ctypes.CDLL(None)  # the program's own symbols: its C library's stdout
        return libc.setvbuf(ctypes.c_void_p.in_dll(libc, "stdout"), None, _IOLBF, 0) == 0
    except (OSError, ValueError, AttributeError, TypeError):
        return False
