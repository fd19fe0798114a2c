"""The output grid of an orthoimage: a north-up raster grid in a CRS (GDAL geotransform, cell centres
at (x0 + (j + 0.5) dx, y0 + (i + 0.5) dy), dy < 0), by default in the UTM zone of the image footprint
with the image's ground sampling distance, over the footprint where the DEM covers it.

A CRS used far from the image (crs.check_output_crs: a UTM zone 200 degrees away mirrors the image) and a
cell size that leaves fewer than crs.MIN_CELLS cells along an axis (crs.check_grid_cells: metres given for a
degree CRS) are InputErrors; `dem_coverage` measures how much of the image the DEM covers."""

import math
from dataclasses import dataclass

import numpy as np
from osgeo import osr

from ..crs import check_grid_cells, transform, wgs84
from ..errors import InputError
from ..geodesy import metres_per_degree
from ..surface.pointcloud import output_srs


@dataclass(frozen=True)
class OutputGrid:
    """`srs` (osr.SpatialReference, x east first), GDAL `geotransform`, `cols` x `rows` cells."""

    srs: osr.SpatialReference
    geotransform: tuple
    cols: int
    rows: int

    def centres(self, rows, cols):
        """(x, y) of the cell centres at row indices `rows` and column indices `cols` (broadcast)."""
        x0, dx, _, y0, _, dy = self.geotransform
        return x0 + (np.asarray(cols, float) + 0.5) * dx, y0 + (np.asarray(rows, float) + 0.5) * dy

    def to_lonlat(self, x, y):
        """WGS 84 (lon, lat) of grid coordinates (arrays of one shape), through PROJ."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        if self.srs.IsSame(wgs84(), ["IGNORE_DATA_AXIS_TO_SRS_AXIS_MAPPING=YES"]):
            return x.copy(), y.copy()
        out = transform(self.srs, wgs84(), np.column_stack([x.ravel(), y.ravel()]), "the output grid")
        return out[:, 0].reshape(x.shape), out[:, 1].reshape(x.shape)


def ground_sampling_distance(model, h):
    """Smaller ground pixel size (m) of the image at its centre and height h: |d ground / d col| and
    |d ground / d row| from image_to_ground one pixel apart."""
    cols, rows = model.size
    c, r = 0.5 * cols, 0.5 * rows
    lon, lat = model.image_to_ground(np.array([c, c + 1.0, c]), np.array([r, r, r + 1.0]), np.full(3, float(h)))
    me, mn = metres_per_degree(lat[0], h)
    d = np.hypot((lon[1:] - lon[0]) * me, (lat[1:] - lat[0]) * mn)
    if not np.all(np.isfinite(d)) or d.min() <= 0:
        raise InputError("the sensor model gives no ground pixel size at the image centre: give the cell size")
    return float(d.min())


def _ring(bounds, n=16):
    """Closed ring of (lon, lat) along the border of (lon_min, lat_min, lon_max, lat_max)."""
    x0, y0, x1, y1 = bounds
    t = np.linspace(0.0, 1.0, n + 1)
    return np.concatenate(
        [
            np.column_stack([x0 + t * (x1 - x0), np.full(n + 1, y0)]),
            np.column_stack([np.full(n + 1, x1), y0 + t * (y1 - y0)]),
            np.column_stack([x1 - t * (x1 - x0), np.full(n + 1, y1)]),
            np.column_stack([np.full(n + 1, x0), y1 - t * (y1 - y0)]),
        ]
    )


def default_grid(model, dem, crs=None, cell_size=None):
    """OutputGrid over the image footprint (at the DEM's lowest and highest heights) clipped to the DEM's
    extent, in `crs` (default: the UTM zone of the footprint) with square cells of `cell_size` CRS units
    (default: the image's ground sampling distance, in degrees on a geographic CRS), snapped to whole
    multiples of the cell size. Raises InputError when the DEM does not overlap the footprint, `crs` is used
    far from it, or the grid would have fewer than 2 or too many cells along an axis (module docstring)."""
    low, high = dem.height_range
    ring = np.vstack([model.footprint(h=low), model.footprint(h=high)])
    srs = output_srs(crs, ring[:, 0], ring[:, 1], "the image")
    if cell_size is None:
        cell_size = ground_sampling_distance(model, 0.5 * (low + high))
        if srs.IsGeographic():
            cell_size /= float(metres_per_degree(float(np.mean(ring[:, 1])))[1])
    cell_size = float(cell_size)
    if not (math.isfinite(cell_size) and cell_size > 0):
        raise InputError(f"the cell size must be a positive number of CRS units, got {cell_size}")
    image_xy = transform(wgs84(), srs, ring, "the image footprint")
    dem_xy = transform(wgs84(), srs, _ring(dem.bounds), "the DEM extent")
    x0, y0 = np.maximum(image_xy.min(axis=0), dem_xy.min(axis=0))[:2]
    x1, y1 = np.minimum(image_xy.max(axis=0), dem_xy.max(axis=0))[:2]
    if not (x1 > x0 and y1 > y0):
        raise InputError("the DEM does not overlap the image footprint: give a DEM that covers the image")
    extent = (x1 - x0, y1 - y0)
    x0, y1 = math.floor(x0 / cell_size) * cell_size, math.ceil(y1 / cell_size) * cell_size
    cols, rows = math.ceil((x1 - x0) / cell_size), math.ceil((y1 - y0) / cell_size)
    check_grid_cells(cols, rows, cell_size, srs, extent, "the orthoimage")
    return OutputGrid(srs, (x0, cell_size, 0.0, y1, 0.0, -cell_size), int(cols), int(rows))


#: dem_coverage looks for DEM heights under the centres of COVERAGE_SAMPLES x COVERAGE_SAMPLES equal parts of the image
COVERAGE_SAMPLES = 32


def dem_coverage(model, dem):
    """The share (0..1) of the image of `model` under which the DEM `dem` (dem_store.StoredDem) has heights: of
    the centres of COVERAGE_SAMPLES x COVERAGE_SAMPLES equal parts of the image, projected at the DEM's middle
    height, those where the DEM's height is defined (inside its extent, off its nodata). A DEM cut to the image
    border covers all of them."""
    cols, rows = model.size
    t = (np.arange(COVERAGE_SAMPLES) + 0.5) / COVERAGE_SAMPLES
    c, r = np.meshgrid(t * cols, t * rows)
    lon, lat = model.image_to_ground_or_nan(c.ravel(), r.ravel(), np.full(c.size, 0.5 * sum(dem.height_range)))
    placed = np.isfinite(lon) & np.isfinite(lat)
    heights = dem.height(lon[placed], lat[placed]) if placed.any() else np.zeros(0)
    return float(np.count_nonzero(np.isfinite(heights))) / c.size
