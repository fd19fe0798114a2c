"""Digital elevation models on a regular longitude/latitude grid with ellipsoidal heights.

The grid uses GDAL's pixel-is-area geotransform (lon0, dlon, 0, lat0, 0, dlat), dlat < 0; a cell's
value is its centre's height. `height` interpolates bilinearly between centres and returns NaN
outside the grid or next to nodata cells.

Heights outside PLAUSIBLE_HEIGHTS (height_range.py) are no terrain on Earth: voids the file does not flag as nodata
(SRTM's -32768), or another unit. They are used as given, with a warning (implausible_heights) that
says how to declare their value as nodata."""

import math

import numpy as np
from numba import njit

from .errors import InputError
from .geodesy import flat_points
from .height_range import PLAUSIBLE_HEIGHTS, outside_plausible


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
    return (grid[i, j] * (1.0 - fx) + grid[i, j1] * fx) * (1.0 - fy) + (
        grid[i1, j] * (1.0 - fx) + grid[i1, j1] * fx
    ) * fy


@njit(cache=True, nogil=True)
def _bilinear_arrays(grid, lon0, dlon, lat0, dlat, lon, lat, out):
    for k in range(lon.size):
        out[k] = bilinear_scalar(grid, lon0, dlon, lat0, dlat, lon[k], lat[k])


def implausible_heights(heights, what="the DEM"):
    """A warning about the finite `heights` (array) outside PLAUSIBLE_HEIGHTS: how many cells, the value
    most of them hold, and how to declare it as nodata; None where every height is plausible. `what`
    names the raster ("the DEM dem.tif")."""
    return implausible_warning(*implausible_values(heights), what)


def implausible_values(heights):
    """(values, counts) of the finite `heights` outside PLAUSIBLE_HEIGHTS: what implausible_warning tells,
    to be added up over the bands of a raster read in parts."""
    heights = np.asarray(heights, dtype=np.float64)
    return np.unique(heights[outside_plausible(heights)], return_counts=True)


def implausible_warning(values, counts, what="the DEM", left_out=None):
    """implausible_heights' warning from the implausible `values` (ascending, unique) and their `counts`. With
    `left_out` (the name of the step's nodata parameter, such as "REFERENCE_NODATA"), the cells are said to be
    left out as voids, as the step does with them; else used as heights."""
    if not len(values):
        return None
    low, high = PLAUSIBLE_HEIGHTS
    total, value = int(np.sum(counts)), float(values[np.argmax(counts)])
    found = (
        f"{total} cells at {value:g} m"
        if len(values) == 1
        else f"{total} cells from {values[0]:g} to {values[-1]:g} m ({max(counts)} of them at {value:g} m)"
    )
    start = (
        f"{what} has {found}, outside the heights of terrain on Earth ({low:g} .. {high:g} m): voids that are "
        f"not flagged as nodata, or heights in another unit. "
    )
    if left_out:
        return start + (
            f"They are left out as voids; declare {value:g} as its nodata value (the {left_out} "
            f"parameter, or gdal_edit.py -a_nodata {value:g} on the file) to say so, or convert the "
            "file to metres if they are heights"
        )
    return start + (
        f"They are used as heights as they are; if they are voids, declare {value:g} as the DEM's nodata "
        f"value (the DEM nodata parameter, or gdal_edit.py -a_nodata {value:g} on the file) and run again"
    )


class ImplausibleTally:
    """implausible_values added up over the parts (bands, windows) of a raster read in parts."""

    def __init__(self):
        self.values, self.counts = np.zeros(0), np.zeros(0, np.int64)

    def add(self, heights):
        """Count the implausible values among `heights`; returns `heights`."""
        values, counts = implausible_values(heights)
        if len(values):
            self.values, inverse = np.unique(np.concatenate([self.values, values]), return_inverse=True)
            self.counts = np.bincount(inverse, np.concatenate([self.counts, counts])).astype(np.int64)
        return heights

    def warning(self, what="the DEM", left_out=None):
        """implausible_warning of all parts."""
        return implausible_warning(self.values, self.counts, what, left_out)


def nodata_as_nan(array, *nodata):
    """`array` as float64 with NaN where it equals one of the `nodata` values (None and NaN: none)."""
    values = np.asarray(array).astype(np.float64)
    for value in nodata:
        if value is not None and not math.isnan(value):
            values[values == value] = np.nan
    return values


def grid_bounds(geotransform, shape):
    """(lon_min, lat_min, lon_max, lat_max) of the outer cell edges of a north-up grid."""
    lon0, dlon, _, lat0, _, dlat = geotransform
    rows, cols = shape
    return lon0, lat0 + rows * dlat, lon0 + cols * dlon, lat0


def check_grid(shape, geotransform):
    """The geotransform of a DEM grid of `shape` as 6 floats; InputError unless the grid is 2-D, at least
    2 x 2 cells and north-up."""
    if len(shape) != 2 or min(shape) < 2:
        raise InputError(f"a DEM needs a 2-D grid of at least 2 x 2 cells, got {tuple(shape)}")
    try:
        gt = tuple(float(v) for v in geotransform)
    except (TypeError, ValueError):
        gt = ()
    if len(gt) != 6 or not all(math.isfinite(v) for v in gt):
        raise InputError(f"a DEM geotransform is 6 finite numbers (GDAL's), got {geotransform!r}")
    if gt[2] != 0.0 or gt[4] != 0.0 or gt[1] <= 0.0 or gt[5] >= 0.0:
        raise InputError("a DEM grid must be north-up (no rotation terms, dlon > 0, dlat < 0)")
    return gt


class Dem:
    """Ellipsoidal heights (metres, WGS 84) on a geographic grid."""

    #: implausible_heights of the heights as read by dem_store.read_dem (None: all plausible, or not read from a file)
    implausible = None

    def __init__(self, heights, geotransform):
        heights = np.ascontiguousarray(heights, dtype=np.float64)
        self.geotransform = check_grid(heights.shape, geotransform)
        if np.all(np.isnan(heights)):
            raise InputError("the DEM holds no valid height (all cells are nodata)")
        self.heights = heights

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
        return cls(
            np.full((2, 2), float(h)), (lon_min, (lon_max - lon_min) / 2, 0.0, lat_max, 0.0, -(lat_max - lat_min) / 2)
        )


def dem_window(heights, geotransform, height_range, bounds):
    """The Dem of the cells of `heights` (the grid of a Dem with `geotransform`, or a disk_array.DiskArray of
    it: only the window is read) that cover the lon/lat `bounds` (lon_min, lat_min, lon_max, lat_max)
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
