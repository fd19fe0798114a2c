"""A point cloud as matching gives it, for the tiled DEM's tests: about 62 000 points on a jittered 12 m
lattice over 3 x 3 km of an analytic surface in UTM 31N, with 300 blunders of 30-80 m, a hole of 250 m
radius (a gap in the DEM) and a sigma_h per point."""

import numpy as np

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.surface import pointcloud

UTM31 = 32631
SIZE = 3000.0  # m: 300 x 300 cells of 10 m


def surface(x, y):
    """The analytic terrain height (m) at UTM 31N x, y."""
    return 400.0 + 120.0 * np.sin(x / 500.0) * np.cos(y / 700.0) + 0.02 * (x - 500000.0)


def write_cloud(path):
    """Write the cloud (module docstring) as LAS to `path`; returns `path`."""
    rng = np.random.default_rng(7)
    x, y = np.meshgrid(np.arange(6.0, SIZE, 12.0), np.arange(6.0, SIZE, 12.0))
    x = 500000.0 + x.ravel() + rng.uniform(-3, 3, x.size)
    y = 4800000.0 + y.ravel() + rng.uniform(-3, 3, y.size)
    keep = np.hypot(x - 501200.0, y - 4801800.0) > 250.0
    x, y = x[keep], y[keep]
    z = surface(x, y) + rng.normal(0, 0.3, len(x))
    blunders = rng.choice(len(x), 300, replace=False)
    z[blunders] += rng.choice([-1, 1], 300) * rng.uniform(30, 80, 300)
    sigma = rng.uniform(0.5, 2.0, len(x)).astype(np.float32)
    pointcloud.write_las(path, x, y, z, {"sigma_h": sigma}, srs(UTM31))
    return path


def read_raster(path):
    """(values with nodata as NaN, geotransform, overview count) of band 1 of a raster."""
    from osgeo import gdal

    ds = gdal.Open(str(path))
    band = ds.GetRasterBand(1)
    values = band.ReadAsArray().astype(float)
    values[values == band.GetNoDataValue()] = np.nan
    return values, ds.GetGeoTransform(), band.GetOverviewCount()
