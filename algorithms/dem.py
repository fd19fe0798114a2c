"""Digital elevation models on a regular longitude/latitude grid with ellipsoidal heights.

The grid uses GDAL's pixel-is-area geotransform (lon0, dlon, 0, lat0, 0, dlat), dlat < 0; a cell's
value is its centre's height. `height` interpolates bilinearly between centres and returns NaN
outside the grid or next to nodata cells.

Heights outside PLAUSIBLE_HEIGHTS are no terrain on Earth: voids the file does not flag as nodata
(SRTM's -32768), or another unit. They are used as given, with a warning (implausible_heights) that
says how to declare their value as nodata."""
import math
import os

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


#: heights (m) of terrain on Earth, ellipsoidal or orthometric, with a margin: the Dead Sea shore lies at
#: -430 m, Everest at 8849 m, and the geoid departs from the ellipsoid by -106 .. +85 m
PLAUSIBLE_HEIGHTS = (-500.0, 9000.0)


def implausible_heights(heights, what="the DEM"):
    """A warning about the finite `heights` (array) outside PLAUSIBLE_HEIGHTS: how many cells, the value
    most of them hold, and how to declare it as nodata; None where every height is plausible. `what`
    names the raster ("the DEM dem.tif")."""
    low, high = PLAUSIBLE_HEIGHTS
    heights = np.asarray(heights, dtype=np.float64)
    bad = heights[(heights < low) | (heights > high)]
    if not bad.size:
        return None
    values, counts = np.unique(bad, return_counts=True)
    value = float(values[np.argmax(counts)])
    found = (f"{bad.size} cells at {value:g} m" if values.size == 1 else
             f"{bad.size} cells from {values[0]:g} to {values[-1]:g} m ({counts.max()} of them at {value:g} m)")
    return (f"{what} has {found}, outside the heights of terrain on Earth ({low:g} .. {high:g} m): voids that are "
            f"not flagged as nodata, or heights in another unit. They are used as heights as they are; if they are "
            f"voids, declare {value:g} as the DEM's nodata value (the DEM nodata parameter, or gdal_edit.py "
            f"-a_nodata {value:g} on the file) and run again")


def grid_bounds(geotransform, shape):
    """(lon_min, lat_min, lon_max, lat_max) of the outer cell edges of a north-up grid."""
    lon0, dlon, _, lat0, _, dlat = geotransform
    rows, cols = shape
    return lon0, lat0 + rows * dlat, lon0 + cols * dlon, lat0


class Dem:
    """Ellipsoidal heights (metres, WGS 84) on a geographic grid."""

    #: implausible_heights of the heights as read by from_file (None: all plausible, or not read from a file)
    implausible = None

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

    #: a window's (dem_window) height range: the whole DEM's
    _height_range = None

    @property
    def height_range(self):
        """(min, max) of the valid heights (of the whole DEM, for a dem_window)."""
        if self._height_range is not None:
            return self._height_range
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
    def from_file(cls, path, nodata=None):
        """Read a DEM raster with ellipsoidal heights; other CRSs are warped (bilinear) to EPSG:4326.

        The raster's own nodata and `nodata` (a value the user declares, such as SRTM's -32768 in a
        file that does not flag its voids) become NaN; `implausible` is implausible_heights of the
        heights as read. InputError where the file cannot be opened or has no CRS (where its cells lie
        would be a guess). Geoid-referenced heights (SRTM) must be converted by the caller."""
        from osgeo import gdal

        from .crs import wgs84
        gdal.UseExceptions()
        try:
            ds = gdal.Open(str(path))
        except RuntimeError as exc:
            if not os.path.exists(path):
                raise InputError(f"cannot open DEM {path}: the file does not exist; check the path") from None
            raise InputError(f"cannot open DEM {path}: GDAL does not read it as a raster ({exc})") from exc
        srs = ds.GetSpatialRef()
        if srs is None:
            raise InputError(f"the DEM {path} has no coordinate reference system, so where its cells lie is unknown: "
                             f"assign the CRS of its coordinates, e.g. 'gdal_edit.py -a_srs EPSG:4326 {path}' for "
                             "longitude/latitude in degrees (or the EPSG code of its map projection), and run again")
        band = ds.GetRasterBand(1)
        heights = band.ReadAsArray().astype(np.float64)
        for value in (band.GetNoDataValue(), nodata):
            if value is not None and not math.isnan(value):
                heights[heights == value] = np.nan
        implausible = implausible_heights(heights, f"the DEM {path}")
        geotransform = ds.GetGeoTransform()
        if not srs.IsSame(wgs84(), ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"]):
            source = gdal.GetDriverByName("MEM").Create("", ds.RasterXSize, ds.RasterYSize, 1, gdal.GDT_Float64)
            source.SetGeoTransform(geotransform)
            source.SetSpatialRef(srs)
            source.GetRasterBand(1).SetNoDataValue(float("nan"))
            source.GetRasterBand(1).WriteArray(heights)
            warped = gdal.Warp("", source, format="MEM", dstSRS="EPSG:4326", resampleAlg="bilinear",
                               outputType=gdal.GDT_Float64, dstNodata=float("nan"))
            heights, geotransform = warped.GetRasterBand(1).ReadAsArray(), warped.GetGeoTransform()
        dem = cls(heights, geotransform)
        dem.implausible = implausible
        return dem


def dem_window(heights, geotransform, height_range, bounds):
    """The Dem of the cells of `heights` (the grid of a Dem with `geotransform`, e.g. memory-mapped from a
    file: only the window is read) that cover the lon/lat `bounds` (lon_min, lat_min, lon_max, lat_max)
    and one more cell around, so that `height` is the whole DEM's there. Its height_range is the whole
    DEM's `height_range`. A window outside the grid is 2 x 2 nodata cells."""
    lon0, dlon, _, lat0, _, dlat = geotransform
    rows, cols = heights.shape
    lon_min, lat_min, lon_max, lat_max = bounds
    c0 = min(max(int(math.floor((lon_min - lon0) / dlon - 0.5)) - 1, 0), cols)
    c1 = max(min(int(math.ceil((lon_max - lon0) / dlon - 0.5)) + 2, cols), 0)
    r0 = min(max(int(math.floor((lat_max - lat0) / dlat - 0.5)) - 1, 0), rows)
    r1 = max(min(int(math.ceil((lat_min - lat0) / dlat - 0.5)) + 2, rows), 0)
    dem = Dem.__new__(Dem)
    if c1 - c0 < 2 or r1 - r0 < 2:
        dem.heights = np.full((2, 2), np.nan)
        half_lon, half_lat = (lon_max - lon_min) / 2 or 1.0, (lat_max - lat_min) / 2 or 1.0
        dem.geotransform = (lon_min, half_lon, 0.0, lat_max, 0.0, -half_lat)
    else:
        dem.heights = np.array(heights[r0:r1, c0:c1], dtype=np.float64)
        dem.geotransform = (lon0 + c0 * dlon, dlon, 0.0, lat0 + r0 * dlat, 0.0, dlat)
    dem._height_range = tuple(float(v) for v in height_range)
    return dem
