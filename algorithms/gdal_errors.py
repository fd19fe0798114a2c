"""GDAL's own messages where the engine reports a failure itself.

GDAL hands every message to the error handler of the thread. With exceptions on, its Python bindings also
raise a failure as a RuntimeError, which the engine turns into its own message; a handler the application
pushed (qgis_process's console filter, plugin/gdal_messages.py) would still print GDAL's line ("ERROR 4:
... No such file or directory") before it, and a warning of a file the engine then refuses ("Warning 1: GPKG:
bad application_id") is printed by any handler. `reported_here` holds GDAL's messages back while the engine
opens a file whose failures it reports in its own words: dropped if the block raises; if it ends normally,
its warnings are passed on to the thread's handler (a failure the engine caught and handled is not one).
atomic.py's writes hold them the same way (HeldMessages), reporting GDAL's failures as a StorageError."""

from osgeo import gdal


class HeldMessages:
    """Inside the `with` block, GDAL's messages in this thread are held (not printed): its failures
    (CE_Failure, CE_Fatal) kept in `failures` for the caller to report, its other messages passed on to the
    thread's handler when the block ends, unless `drop_on_error` and the block raised."""

    def __init__(self, drop_on_error=False):
        self.drop_on_error, self.failures, self.passed = drop_on_error, [], []

    def __call__(self, level, number, message):
        if level >= gdal.CE_Failure:
            self.failures.append(message)
        else:
            self.passed.append((level, number, message))

    def __enter__(self):
        gdal.PushErrorHandler(self)
        return self

    def __exit__(self, exc_type, *exc):
        gdal.PopErrorHandler()
        if not (self.drop_on_error and exc_type is not None):
            for level, number, message in self.passed:
                gdal.Error(level, number, message)
        return False


def reported_here():
    """HeldMessages for the engine's own report (module docstring): dropped if the block raises, its warnings
    passed on if it ends normally (a failure the engine caught and handled is not one)."""
    return HeldMessages(drop_on_error=True)
