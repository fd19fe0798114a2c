"""Plain numpy reference for raster lookups in tests (independent of algorithms/dem.py)."""

import numpy as np
from osgeo import gdal


def bilinear(path, lon, lat):
    """Bilinear interpolation between the cell centres of a north-up raster at (lon, lat) (its CRS)."""
    ds = gdal.Open(str(path))
    z, (x0, dx, _, y0, _, dy) = ds.ReadAsArray().astype(float), ds.GetGeoTransform()
    x, y = (lon - x0) / dx - 0.5, (lat - y0) / dy - 0.5
    j, i = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - j, y - i
    return (
        z[i, j] * (1 - fx) * (1 - fy)
        + z[i, j + 1] * fx * (1 - fy)
        + z[i + 1, j] * (1 - fx) * fy
        + z[i + 1, j + 1] * fx * fy
    )
