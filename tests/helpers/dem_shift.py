"""DEMs with a known shift, shared by the co-registration and merge tests and the xdem benchmark
(scripts/coregistration_peers.py): an analytic terrain (ground truth by construction), the simulated true DSM warped
to UTM, and the unstable-terrain mask of the simulated land cover."""

import numpy as np
from osgeo import gdal

from pushbroom.algorithms.simulation.terrain import CITY, FOREST, WATER
from pushbroom.algorithms.surface.geotiff import write_code_raster

#: the analytic DEMs' cell (m) and lattice origin (UTM 31N)
CELL = 10.0
ORIGIN = (500_000.0, 4_800_000.0)
UTM = 32631
#: nodata of the warped DSMs
VOID = -9999.0


def terrain(x, y):
    """Hills of 200-500 m wavelength, slopes facing every way."""
    return (
        300 + 40 * np.sin(x / 230.0) * np.cos(y / 310.0) + 25 * np.sin((x + y) / 150.0) + 10 * np.cos(x / 90 - y / 120)
    )


def centres(origin, cols, cell=CELL, rows=None):
    """(x, y) meshgrids of the centres of `rows` x `cols` cells of `cell` m (square where rows is None) from the
    north-west corner `origin`."""
    rows = cols if rows is None else rows
    return np.meshgrid(origin[0] + (np.arange(cols) + 0.5) * cell, origin[1] - (np.arange(rows) + 0.5) * cell)


def warped_dsm(source, path, cell, epsg, bounds=None, resampling="cubic"):
    """(heights with NaN voids, geotransform, CRS) of the raster `source` warped to EPSG:`epsg` at `cell` m by
    `resampling`, over `bounds` where given, into `path`, with the exact transformation (gdalwarp's default 0.125 px
    approximation moves the simulated DSM 0.2 m north, which co-registration finds)."""
    gdal.Warp(
        str(path),
        str(source),
        dstSRS=f"EPSG:{epsg}",
        xRes=cell,
        yRes=cell,
        resampleAlg=resampling,
        dstNodata=VOID,
        errorThreshold=0,
        outputBounds=bounds,
    )
    ds = gdal.Open(str(path))
    values = ds.GetRasterBand(1).ReadAsArray().astype(float)
    values[values == VOID] = np.nan
    return values, ds.GetGeoTransform(), ds.GetSpatialRef().Clone()  # not tied to `ds`, freed on return


def unstable_mask(classes, path):
    """The simulated land cover `classes` (its raster) as an unstable-terrain mask at `path`: 1 forest, town and
    water, 0 elsewhere."""
    ds = gdal.Open(str(classes))
    codes = np.isin(ds.GetRasterBand(1).ReadAsArray(), (FOREST, CITY, WATER))
    return str(write_code_raster(str(path), codes, ds.GetGeoTransform(), ds.GetSpatialRef().Clone()))
