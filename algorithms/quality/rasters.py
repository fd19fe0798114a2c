"""Single-band rasters for the accuracy assessment, read with GDAL: a height raster as float64 with
NaN for nodata, read by the window that covers the points, block by block for points spread over a
large raster (never a whole SRTM tile for a 3 km scene, nor a whole 60 km DSM at once), or resampled
onto another raster's grid with gdalwarp (the reference onto the tested DEM: bilinear, or the average of
the reference cells inside a DEM cell when the reference is finer).
Grids are north-up (GDAL geotransform, pixel-is-area)."""

from dataclasses import dataclass

import numpy as np
from osgeo import gdal, osr

from ..crs import srs as parse_crs
from ..dem import nodata_as_nan
from ..errors import InputError
from ..geodesy import metres_per_degree
from ..tiling import cell_blocks


@dataclass
class Grid:
    """A north-up grid: values (rows, cols; NaN = nodata), GDAL geotransform, CRS."""

    values: np.ndarray
    geotransform: tuple
    srs: osr.SpatialReference

    @property
    def shape(self):
        return self.values.shape

    def centres(self):
        """(x, y) of every cell centre, arrays of the grid's shape, in the grid's CRS."""
        x0, dx, _, y0, _, dy = self.geotransform
        rows, cols = self.shape
        return np.meshgrid(x0 + (np.arange(cols) + 0.5) * dx, y0 + (np.arange(rows) + 0.5) * dy)

    def cell_metres(self):
        """(east, north) cell size in metres."""
        return cell_metres(self.geotransform, self.srs, self.shape[0])


def metres_per_unit(geotransform, srs, rows):
    """(east, north) metres per unit of the CRS `srs` of a grid of `rows` rows (at its centre for a geographic CRS)."""
    if srs.IsGeographic():
        east, north = metres_per_degree(geotransform[3] + 0.5 * rows * geotransform[5])
        return float(east), float(north)
    factor = srs.GetLinearUnits()
    return factor, factor


def cell_metres(geotransform, srs, rows):
    """(east, north) cell size in metres of a grid of `rows` rows (at its centre for a geographic CRS)."""
    east, north = metres_per_unit(geotransform, srs, rows)
    return geotransform[1] * east, abs(geotransform[5]) * north


#: the relative difference of cell sizes below which a raster is not finer than another
SAME_CELL = 0.01


def mean_cell(ds):
    """The mean cell side (m) of the raster `ds` (the geometric mean of cell_metres at its centre)."""
    return float(np.sqrt(np.prod(cell_metres(ds.GetGeoTransform(), raster_srs(ds), ds.RasterYSize))))


def resampling_for(ds, cell):
    """gdalwarp's resampling of the raster `ds` onto cells of `cell` m: the average of its cells inside a cell where
    it is finer (by more than SAME_CELL), bilinear otherwise."""
    return "average" if mean_cell(ds) < cell * (1 - SAME_CELL) else "bilinear"


def open_raster(path, what):
    """gdal.Dataset of a north-up, georeferenced raster (InputError naming `what` otherwise)."""
    gdal.UseExceptions()
    try:
        ds = gdal.Open(str(path))
    except RuntimeError as exc:
        raise InputError(f"cannot open the {what} {path}: {exc}") from exc
    gt = ds.GetGeoTransform()
    if ds.GetSpatialRef() is None:
        raise InputError(
            f"the {what} {path} has no coordinate reference system: assign one (e.g. with gdal_edit.py "
            "-a_srs) and run again"
        )
    if gt[2] != 0.0 or gt[4] != 0.0 or gt[5] >= 0.0:
        raise InputError(f"the {what} {path} is not a north-up grid: warp it (gdalwarp) first")
    return ds


def raster_srs(ds):
    """The horizontal CRS of the raster `ds` (a compound CRS's vertical part stripped: the heights' datum is declared
    and checked apart, height_differences.check_stated, and gdalwarp must never shift heights on its own)."""
    out = parse_crs(ds.GetSpatialRef())
    if out.IsCompound():
        out.StripVertical()
    return out


def read_grid(ds, nodata=None, window=None):
    """The first band as a Grid, whole or its `window` (c0, r0, c1, r1); its nodata and `nodata` (a declared
    void value) are NaN."""
    band = ds.GetRasterBand(1)
    c0, r0, c1, r1 = window or (0, 0, ds.RasterXSize, ds.RasterYSize)
    x0, dx, _, y0, _, dy = ds.GetGeoTransform()
    return Grid(
        nodata_as_nan(band.ReadAsArray(c0, r0, c1 - c0, r1 - r0), band.GetNoDataValue(), nodata),
        (x0 + c0 * dx, dx, 0.0, y0 + r0 * dy, 0.0, dy),
        raster_srs(ds),
    )


def read_window(ds, x, y, what, margin=2, nodata=None):
    """Grid of the cells of `ds` around points (x, y) given in its CRS, `margin` cells beyond them; its
    nodata and `nodata` (a declared void value) are NaN. InputError when no point falls on the raster."""
    x0, dx, _, y0, _, dy = ds.GetGeoTransform()
    finite = np.isfinite(x) & np.isfinite(y)
    if finite.any():
        c, r = (x[finite] - x0) / dx, (y[finite] - y0) / dy
        c0, c1 = max(int(np.floor(c.min())) - margin, 0), min(int(np.ceil(c.max())) + margin, ds.RasterXSize)
        r0, r1 = max(int(np.floor(r.min())) - margin, 0), min(int(np.ceil(r.max())) + margin, ds.RasterYSize)
    if not finite.any() or c1 - c0 < 2 or r1 - r0 < 2:
        raise InputError(f"the {what} does not overlap the data to assess: choose a {what} that covers it")
    band = ds.GetRasterBand(1)
    values = nodata_as_nan(band.ReadAsArray(c0, r0, c1 - c0, r1 - r0), band.GetNoDataValue(), nodata)
    return Grid(values, (x0 + c0 * dx, dx, 0.0, y0 + r0 * dy, 0.0, dy), raster_srs(ds))


#: side (cells) of the blocks in which points sample a raster (by_blocks)
BLOCK = 1024


def by_blocks(ds, x, y):
    """The indices of the points (x, y in the CRS of `ds`) in each BLOCK x BLOCK cell block of `ds` that holds
    some (tiling.cell_blocks), so that points spread over a large raster read it one block at a time
    (read_window of a block's points). Points off the raster are in no block."""
    x0, dx, _, y0, _, dy = ds.GetGeoTransform()
    return cell_blocks((np.asarray(x) - x0) / dx, (np.asarray(y) - y0) / dy, (ds.RasterYSize, ds.RasterXSize), BLOCK)


def outline(grid, n=64):
    """(x, y) of n points along each of the four outer cell edges of `grid`, in its CRS (to find the cells
    of another raster under it with read_window)."""
    x0, dx, _, y0, _, dy = grid.geotransform
    rows, cols = grid.shape
    t = np.linspace(0.0, 1.0, n)
    x1, y1 = x0 + cols * dx, y0 + rows * dy
    return (
        np.concatenate([x0 + t * (x1 - x0), x0 + t * (x1 - x0), np.full(n, x0), np.full(n, x1)]),
        np.concatenate([np.full(n, y0), np.full(n, y1), y0 + t * (y1 - y0), y0 + t * (y1 - y0)]),
    )


def memory_dataset(grid):
    """An in-memory float64 GDAL dataset of `grid`, NaN as its nodata (for warp_to)."""
    rows, cols = grid.shape
    ds = gdal.GetDriverByName("MEM").Create("", cols, rows, 1, gdal.GDT_Float64)
    ds.SetGeoTransform(grid.geotransform)
    ds.SetSpatialRef(grid.srs)
    band = ds.GetRasterBand(1)
    band.SetNoDataValue(float("nan"))
    band.WriteArray(grid.values)
    return ds


def warp_to(ds, grid, resampling):
    """Band 1 of `ds` resampled (gdalwarp `resampling`) onto `grid`'s cells and CRS, float64 with NaN; from
    the full-resolution band (never from an overview, which gdalwarp would pick when downsampling and
    whose cells need not align with the band's) and with the exact transformation (error threshold 0)."""
    rows, cols = grid.shape
    x0, dx, _, y0, _, dy = grid.geotransform
    band = ds.GetRasterBand(1)
    nodata = band.GetNoDataValue()
    out = gdal.Warp(
        "",
        ds,
        format="MEM",
        dstSRS=grid.srs.ExportToWkt(),
        width=cols,
        height=rows,
        outputBounds=(x0, y0 + rows * dy, x0 + cols * dx, y0),
        resampleAlg=resampling,
        outputType=gdal.GDT_Float64,
        srcNodata=nodata,
        dstNodata=float("nan"),
        errorThreshold=0,
        overviewLevel="NONE",
    )
    return out.GetRasterBand(1).ReadAsArray()


def gradient(grid):
    """(dz/de, dz/dn) in m/m of a height Grid by central differences (np.gradient) with metric cell sizes, on a
    geographic grid those at each row's latitude (so that a window's gradient is the whole grid's there); n is north
    (the rows run south)."""
    x0, dx, _, y0, _, dy = grid.geotransform
    if grid.srs.IsGeographic():
        east, north = metres_per_degree(y0 + (np.arange(grid.shape[0]) + 0.5) * dy)
        east, north = (dx * east)[:, None], (dy * north)[:, None]
    else:
        east, north = (v * grid.srs.GetLinearUnits() for v in (dx, dy))
    gy, gx = np.gradient(grid.values)
    return gx / east, gy / north


def slope_degrees(grid):
    """Slope (degrees) of a height Grid (gradient)."""
    g_e, g_n = gradient(grid)
    return np.degrees(np.arctan(np.hypot(g_e, g_n)))
