"""Digital elevation models on a regular longitude/latitude grid with ellipsoidal heights.

The grid uses GDAL's pixel-is-area geotransform (lon0, dlon, 0, lat0, 0, dlat), dlat < 0; a cell's
value is its centre's height. `height` interpolates bilinearly between centres and returns NaN
outside the grid or next to nodata cells."""
import math

import numpy as np
from numba import njit

from .errors import InputError
from .geodesy import flat_points


@njit(cache=True, nogil=True)
def bilinear_scalar(grid, lon0, dlon, lat0, dlat, lon, lat):
    """Bilinear interpolation of `grid` at (lon, lat); NaN outside the centres' hull."""
    x = (lon - lon0) / dlon - 0.5
    y = (lat - lat0) / dlat - 0.5
    rows, cols = grid.shape
    if not (x >= 0.0 and y >= 0.0 and x <= cols - 1 and y <= rows - 1):
        return math.nan
    i = min(int(y), rows - 2) if rows > 1 else 0
    j = min(int(x), cols - 2) if cols > 1 else 0
    fy = y - i
    fx = x - j
    i1 = min(i + 1, rows - 1)
    j1 = min(j + 1, cols - 1)
    return ((grid[i, j] * (1.0 - fx) + grid[i, j1] * fx) * (1.0 - fy)
            + (grid[i1, j] * (1.0 - fx) + grid[i1, j1] * fx) * fy)


@njit(cache=True, nogil=True)
def _bilinear_arrays(grid, lon0, dlon, lat0, dlat, lon, lat, out):
    for k in range(lon.size):
        out[k] = bilinear_scalar(grid, lon0, dlon, lat0, dlat, lon[k], lat[k])


def grid_bounds(geotransform, shape):
    """(lon_min, lat_min, lon_max, lat_max) of the outer cell edges of a north-up grid."""
    lon0, dlon, _, lat0, _, dlat = geotransform
    rows, cols = shape
    return lon0, lat0 + rows * dlat, lon0 + cols * dlon, lat0


class Dem:
    """Ellipsoidal heights (metres, WGS 84) on a geographic grid."""

    def __init__(self, heights, geotransform):
        heights = np.ascontiguousarray(heights, dtype=np.float64)
        if heights.ndim != 2 or min(heights.shape) < 2:
            raise InputError(f"a DEM needs a 2-D grid of at least 2 x 2 cells, got {heights.shape}")
        try:
            gt = tuple(float(v) for v in geotransform)
        except (TypeError, ValueError):
            gt = ()
        if len(gt) != 6 or not all(math.isfinite(v) for v in gt):
            raise InputError(f"a DEM geotransform is 6 finite numbers (GDAL's), got {geotransform!r}")
        if gt[2] != 0.0 or gt[4] != 0.0 or gt[1] <= 0.0 or gt[5] >= 0.0:
            raise InputError("a DEM grid must be north-up (no rotation terms, dlon > 0, dlat < 0)")
        if np.all(np.isnan(heights)):
            raise InputError("the DEM holds no valid height (all cells are nodata)")
        self.heights = heights
        self.geotransform = gt

    @property
    def shape(self):
        return self.heights.shape

    @property
    def bounds(self):
        """(lon_min, lat_min, lon_max, lat_max) of the grid's outer cell edges."""
        return grid_bounds(self.geotransform, self.heights.shape)

    @property
    def height_range(self):
        """(min, max) of the valid heights."""
        return float(np.nanmin(self.heights)), float(np.nanmax(self.heights))

    def height(self, lon, lat):
        """Bilinear height at (lon, lat) (arrays or scalars); NaN where undefined."""
        (lon, lat), shape, scalar = flat_points(lon, lat)
        out = np.empty(lon.size)
        lon0, dlon, _, lat0, _, dlat = self.geotransform
        _bilinear_arrays(self.heights, lon0, dlon, lat0, dlat, lon, lat, out)
        return float(out[0]) if scalar else out.reshape(shape)

    @classmethod
    def constant(cls, h, bounds):
        """A flat DEM at height `h` over bounds (lon_min, lat_min, lon_max, lat_max)."""
        lon_min, lat_min, lon_max, lat_max = bounds
        return cls(np.full((2, 2), float(h)),
                   (lon_min, (lon_max - lon_min) / 2, 0.0, lat_max, 0.0, -(lat_max - lat_min) / 2))

    @classmethod
    def from_file(cls, path):
        """Read a DEM raster with ellipsoidal heights; other CRSs are warped to EPSG:4326.

        Nodata becomes NaN. Geoid-referenced heights (SRTM) must be converted by the caller."""
        from osgeo import gdal

        from .crs import wgs84
        gdal.UseExceptions()
        try:
            ds = gdal.Open(str(path))
        except RuntimeError as exc:
            raise InputError(f"cannot open DEM {path}: {exc}") from exc
        srs = ds.GetSpatialRef()
        if srs is not None and not srs.IsSame(wgs84(), ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"]):
            ds = gdal.Warp("", ds, format="MEM", dstSRS="EPSG:4326", resampleAlg="bilinear",
                           outputType=gdal.GDT_Float64, dstNodata=float("nan"))
        band = ds.GetRasterBand(1)
        heights = band.ReadAsArray().astype(np.float64)
        nodata = band.GetNoDataValue()
        if nodata is not None and not math.isnan(nodata):
            heights[heights == nodata] = np.nan
        return cls(heights, ds.GetGeoTransform())
