"""Block adjustment: observations, the bundle adjustment with its statistics and blunder tests,
and the automatic choice of free orientation parameters."""
