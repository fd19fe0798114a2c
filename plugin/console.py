"""The console qgis_process writes a step's lines to.

qgis_process prints the feedback's lines (pushInfo, pushWarning) through C's stdout. Where that is a pipe or a
file (a script's log, a batch system), C buffers it in blocks of 4 KB: the lines of a long step then reach the
log minutes late, all at once at its end. `line_buffered_stdout` makes C's stdout line-buffered, so each line
leaves as it is written. glibc's setvbuf with no buffer of ours only sets the stream's mode (a call after output
is safe there); elsewhere (no C library found) nothing changes."""
import ctypes
import ctypes.util

_IOLBF = 1          # glibc's <stdio.h>


def line_buffered_stdout() -> bool:
    """Make C's stdout line-buffered (module docstring); whether it was done."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        stream = ctypes.c_void_p.in_dll(libc, "stdout")
        return libc.setvbuf(stream, None, _IOLBF, 0) == 0
    except (OSError, ValueError, AttributeError, TypeError):
        return False
