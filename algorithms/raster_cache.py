"""GDAL's raster block cache, bounded while a step runs.

GDAL keeps the blocks it reads and writes in one cache per process, by default up to 5 % of the RAM
(1.2 GB on a 24 GiB machine). The steps stream rasters by bands and tiles, reading each block about
once, so a large cache does not make them faster; but it fills as far as the rasters reach, so a
step's memory would follow the scene up to that bound. While a step runs, the cache of its process
(`bounded`) and of its worker processes (`hold_in_worker`, before each task) is held to STEP_CACHE."""

import contextlib
import threading

from osgeo import gdal

#: GDAL's block cache (bytes) while a step runs
STEP_CACHE = 64 * 2**20

_lock = threading.Lock()
_held = {"depth": 0, "previous": None}


@contextlib.contextmanager
def bounded():
    """Hold this process's GDAL cache to STEP_CACHE (never raise it) while any step of the process is inside
    the block (steps may overlap on QGIS's background threads); the last to leave restores the setting the
    first found."""
    with _lock:
        if _held["depth"] == 0:
            _held["previous"] = gdal.GetCacheMax()
            gdal.SetCacheMax(min(_held["previous"], STEP_CACHE))
        _held["depth"] += 1
    try:
        yield
    finally:
        with _lock:
            _held["depth"] -= 1
            if _held["depth"] == 0:
                gdal.SetCacheMax(_held["previous"])


def hold_in_worker():
    """Hold the GDAL cache of a worker process (local processes and Dask: task_runtime.in_worker, before each task)
    to STEP_CACHE; a worker runs only the steps' tasks, so the bound stays."""
    if gdal.GetCacheMax() > STEP_CACHE:
        gdal.SetCacheMax(STEP_CACHE)
