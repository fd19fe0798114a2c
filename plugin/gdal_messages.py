"""GDAL's and Qt's console messages under qgis_process.

QGIS prints "ERROR 1: Unable to compute a transformation between pixel/line and georeferenced
coordinates ..." whenever it loads an image without georeferencing as a raster layer, and qgis_process
loads every raster parameter while it checks the parameters, before any algorithm code runs. Level-1A
images (SPOT IMAGERY.TIF, raw RPC imagery) have no georeferencing by design: their geometry is the sensor
model. For a raw RPC image QGIS's GDAL provider also says "Creating Warped VRT." (a Qt warning) each time
it loads one. Neither is a failure; both read as one.

`install_console_filter` pushes a GDAL handler in qgis_process's main thread that prints every message as
GDAL's default handler does, except:

- the no-georeferencing message;
- a failure met inside a call of GDAL's Python bindings with exceptions on: the bindings raise it as a
  Python exception, which the code that made the call reports (Pushbroom in its own words); printed too,
  GDAL's line would come first ("ERROR 4: ... No such file or directory" before Pushbroom's message).
  GDAL's default handler leaves such failures to the exception as well; a pushed handler is called for every
  message, so this one checks.

and a Qt message handler that drops QGIS's "Logged warning: Creating Warped VRT." and prints every other Qt
message as Qt's default handler does (qgis_process installs none of its own)."""

import sys

from osgeo import gdal
from qgis.PyQt.QtCore import qInstallMessageHandler

NO_GEOREFERENCING = "Unable to compute a transformation between pixel/line and georeferenced coordinates"
#: QGIS's GDAL provider's note (through QgsLogger::warning) for a raster it warps by its RPC or GCPs to show it
WARPED_VRT = "Creating Warped VRT."
_LEVELS = {gdal.CE_Warning: "Warning", gdal.CE_Failure: "ERROR", gdal.CE_Fatal: "FATAL"}
#: Python modules of GDAL's bindings, whose calls raise a failure as an exception where exceptions are on
_BINDINGS = ("osgeo.gdal", "osgeo.ogr", "osgeo.osr", "osgeo.gdal_array", "osgeo.gnm")
_installed = []


def raised_by_bindings(level):
    """Whether a GDAL message of `level` reported now is a failure inside a call of GDAL's Python bindings
    with exceptions on (the caller of the handler: the binding's Python wrapper), i.e. one the caller gets as
    a RuntimeError."""
    if level < gdal.CE_Failure:
        return False
    try:
        frame = sys._getframe(2)  # 0: this function, 1: the handler, 2: the code that called into GDAL
    except ValueError:  # the handler called from C++ with no Python caller: not the bindings
        return False
    module = sys.modules.get(frame.f_globals.get("__name__", ""))
    if module is None or module.__name__ not in _BINDINGS:
        return False
    uses = getattr(module, "GetUseExceptions", None) or gdal.GetUseExceptions
    return bool(uses())


def _console(level, number, message):
    if NO_GEOREFERENCING in message or level not in _LEVELS or raised_by_bindings(level):
        return
    sys.stderr.write(f"{_LEVELS[level]} {number}: {message}\n")


def _qt_console(kind, context, message):
    if message.strip().endswith(WARPED_VRT):
        return
    sys.stderr.write(f"{message}\n")


def install_console_filter():
    """Install the filtering handlers once per process (the QGIS application must be qgis_process)."""
    if not _installed:
        gdal.PushErrorHandler(_console)
        qInstallMessageHandler(_qt_console)
        _installed.append(_console)
