"""Bad inputs the bad-input tests share (tests/algorithms/test_bad_input_*.py and their Processing
counterparts in tests/plugin): DEMs without a CRS or with unflagged voids, a DIMAP product without its raster,
LAS files with any CRS or none, and the message of a refused Processing run."""

import shutil
from pathlib import Path

import numpy as np
from osgeo import gdal

#: the void block of the test DEMs: rows, columns of the simulated DSM (889 x 1011 cells)
VOID = (slice(400, 500), slice(300, 400))
VOID_CELLS = 100 * 100


def copy_dem(source, path, crs=True, voids=False):
    """The DSM `source` as a Float32 GeoTIFF: with or without its CRS, optionally with the VOID block at
    -32767 and no nodata flagged (as an SRTM tile converted without -a_nodata)."""
    ds = gdal.Open(str(source))
    z = ds.GetRasterBand(1).ReadAsArray().astype(np.float32)
    if voids:
        z[VOID] = -32767
    out = gdal.GetDriverByName("GTiff").Create(str(path), ds.RasterXSize, ds.RasterYSize, 1, gdal.GDT_Float32)
    out.SetGeoTransform(ds.GetGeoTransform())
    if crs:
        out.SetProjection(ds.GetProjection())
    out.GetRasterBand(1).WriteArray(z)
    out = None
    return str(path)


def product_without_raster(scene, folder):
    """A copy of the simulated HRG product folder in `folder` without its IMAGERY.TIF."""
    product = Path(folder) / "HRG"
    shutil.copytree(Path(scene["images"]["HRG"]["metadata"]).parent, product)
    (product / "IMAGERY.TIF").unlink()
    return product


def las(path, x, y, z, wkt=None):
    """A LAS 1.4 file of the points with `wkt` in a WKT VLR (None: no CRS VLR at all)."""
    from pushbroom.algorithms.surface.pointcloud import laspy_module

    laspy = laspy_module()
    header = laspy.LasHeader(point_format=6, version="1.4")
    step = 1e-8 if np.abs(x).max() <= 360 else 1e-3  # degrees or metres
    header.scales, header.offsets = np.array([step, step, 1e-3]), np.floor([x.min(), y.min(), z.min()])
    if wkt is not None:
        header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(wkt))
    data = laspy.LasData(header)
    data.x, data.y, data.z = x, y, z
    data.write(str(path))
    return str(path)


def processing_error(algorithm, parameters):
    """The message of the QgsProcessingException of `algorithm` (only the text is kept: a kept traceback
    holding QGIS objects crashes the interpreter's last garbage collection after QGIS exits)."""
    from qgis import processing
    from qgis.core import QgsProcessingContext, QgsProcessingException

    try:
        processing.run(algorithm, parameters, context=QgsProcessingContext())
    except QgsProcessingException as exc:
        return str(exc)
    raise AssertionError(f"{algorithm} accepted {parameters}")
