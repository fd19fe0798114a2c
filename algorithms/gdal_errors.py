"""GDAL's own messages where the engine reports a failure itself.

GDAL hands every message to the error handler of the thread. With exceptions on, its Python bindings also
raise a failure as a RuntimeError, which the engine turns into its own message; a handler the application
pushed (qgis_process's console filter, plugin/gdal_messages.py) would still print GDAL's line ("ERROR 4:
... No such file or directory") before it, and a warning of a file the engine then refuses ("Warning 1: GPKG:
bad application_id") is printed by any handler. `reported_here` holds GDAL's messages back while the engine
opens a file whose failures it reports in its own words: dropped if the block raises; if it ends normally,
its warnings are passed on to the thread's handler (a failure the engine caught and handled is not one)."""
import contextlib

from osgeo import gdal


class _Held:
    """A GDAL error handler that keeps (level, number, message) of every message."""

    def __init__(self):
        self.messages = []

    def __call__(self, level, number, message):
        self.messages.append((level, number, message))


@contextlib.contextmanager
def reported_here():
    """Yield; GDAL's messages in this thread meanwhile are dropped if the block raises (the engine's own
    message reports the failure), else its warnings are passed on to the thread's handler (module docstring)."""
    held = _Held()
    gdal.PushErrorHandler(held)
    try:
        yield
    finally:
        gdal.PopErrorHandler()
    for level, number, message in held.messages:
        if level < gdal.CE_Failure:
            gdal.Error(level, number, message)
