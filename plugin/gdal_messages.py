"""GDAL's console messages under qgis_process.

QGIS prints "ERROR 1: Unable to compute a transformation between pixel/line and georeferenced
coordinates ..." whenever it loads an image without georeferencing as a raster layer, and qgis_process
loads every raster parameter while it checks the parameters, before any algorithm code runs. Level-1A
images (SPOT IMAGERY.TIF, raw RPC imagery) have no georeferencing by design: their geometry is the sensor
model. `install_console_filter` drops exactly that message in qgis_process's main thread and prints every
other GDAL message as GDAL's default handler does."""
import sys

from osgeo import gdal

NO_GEOREFERENCING = "Unable to compute a transformation between pixel/line and georeferenced coordinates"
_LEVELS = {gdal.CE_Warning: "Warning", gdal.CE_Failure: "ERROR", gdal.CE_Fatal: "FATAL"}
_installed = []


def _console(level, number, message):
    if NO_GEOREFERENCING in message or level not in _LEVELS:
        return
    sys.stderr.write(f"{_LEVELS[level]} {number}: {message}\n")


def install_console_filter():
    """Push the filtering handler once per process (the QGIS application must be qgis_process)."""
    if not _installed:
        gdal.PushErrorHandler(_console)
        _installed.append(_console)
