"""Orthoimage by the indirect method (Heipke et al. 1992, section 4.1): for every output cell its ground point
(x, y; h from the DEM) is mapped into the image with any sensor model (mapping.py: coarse grid with a stated
error bound) and the image is resampled there (resampling.py), optionally with occluded cells as nodata
(occlusion.py). The step's entry point is steps/orthoimage.py's orthorectify_image.

The output is processed in square tiles (tiling.tile_grid), each a task on the chosen execution
(execution.run_tasks: threads, local processes or Dask). Per tile only the image window it needs is
read (GDAL) and only the DEM window under the tile's footprint, widened by the reach of an occluding
ray (the DEM's height range times the slope of the lines of sight), is taken from the DEM, which the
step reads from its stored file (dem_store.StoredDem.window; a DEM in memory is stored in a work folder beside
the output first). So
memory follows the tile and the number of workers, and the result does not depend on the execution.
Each task writes its tile as a GeoTIFF; GDAL assembles them (a VRT translated into a tiled,
DEFLATE-compressed GeoTIFF of the image's data type with nodata set and overviews,
geotiff.assemble_tiles) under a temporary name renamed at the end (a cancel leaves no file)."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from osgeo import gdal, gdal_array

from .. import progress
from ..atomic import atomic_path, closing, work_dir
from ..crs import srs as parse_crs
from ..dem_store import as_stored
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..progress import Feedback
from ..surface.geotiff import Frame, assemble_tiles, raster_output
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from . import occlusion, resampling
from .grid import OutputGrid, default_grid
from .mapping import START_STEP, TileMapper

TILE = 512
CREATION_OPTIONS = ("TILED=YES", "BLOCKXSIZE=256", "BLOCKYSIZE=256", "COMPRESS=DEFLATE", "BIGTIFF=IF_SAFER")


@dataclass(frozen=True)
class OrthoSettings:
    """How `orthorectify` makes the orthoimage: the output grid's CRS `crs` and `cell_size` (where no grid
    is given: default_grid), `resampling_method` 'bilinear' or 'bicubic', `occlusion_mask` (occluded cells
    as nodata), `max_error` (px: the bound of the coarse-grid interpolation, mapping.py) from the coarse
    step `start_step`, output tiles of `tile` cells a side, internal `overviews`, a Cloud-Optimised GeoTIFF
    where `cog`."""

    crs: str | None = None
    cell_size: float | None = None
    resampling_method: str = "bilinear"
    occlusion_mask: bool = False
    max_error: float = 0.01
    start_step: int = START_STEP
    tile: int = TILE
    overviews: bool = True
    cog: bool = False


@dataclass
class OrthoResult:
    """What orthorectify wrote: `path`, `grid`, `bound` (largest achieved coarse-grid error bound, px),
    `steps` ({coarse step: tiles}), `cells` (valid cells written), `occluded` (cells set to nodata as
    occluded), `seconds`."""

    path: str
    grid: object
    bound: float
    steps: dict
    cells: int
    occluded: int
    seconds: float

    def summary(self):
        steps = ", ".join(f"{n} x step {s}" for s, n in sorted(self.steps.items(), reverse=True))
        return (
            f"{self.grid.cols} x {self.grid.rows} cells, {self.cells} with image values, {self.occluded} "
            f"occluded; coarse-grid tiles: {steps}; achieved interpolation bound {self.bound:.2g} px; "
            f"{self.seconds:.1f} s"
        )


def _nodata(band, dtype):
    """The image's nodata value, else 0 for integer images (DIMAP's DN 0) and NaN for floats."""
    value = band.GetNoDataValue()
    if value is not None:
        return value
    return 0 if np.issubdtype(dtype, np.integer) else math.nan


def _to_dtype(values, dtype, nodata):
    """Resampled values rounded and clipped to `dtype`, never equal to an integer nodata at its range's end."""
    if not np.issubdtype(dtype, np.integer):
        return values.astype(dtype)
    info = np.iinfo(dtype)
    lo = info.min + 1 if nodata == info.min else info.min
    hi = info.max - 1 if nodata == info.max else info.max
    return np.clip(np.rint(values), lo, hi).astype(dtype)


class _TileWorker:
    """Computes one output tile: mapping, occlusion, resampling (one GDAL handle per call: thread-safe)."""

    def __init__(self, image, model, dem, mapper, method, occlusion_on, dtype, nodata):
        self.image, self.model, self.dem, self.mapper = image, model, dem, mapper
        self.method, self.occlusion_on, self.dtype, self.nodata = method, occlusion_on, dtype, nodata

    def __call__(self, window):
        row0, col0, rows, cols = window
        tile = self.mapper.tile(row0, col0, rows, cols)
        col, row = tile.col.ravel(), tile.row.ravel()
        n_occluded = 0
        if self.occlusion_on:
            direction = self._direction(tile)
            if direction is not None:
                hidden = occlusion.occluded(self.dem, tile.lon.ravel(), tile.lat.ravel(), tile.h.ravel(), direction)
                hidden &= np.isfinite(col)
                n_occluded = int(hidden.sum())
                col = np.where(hidden, np.nan, col)
        try:
            ds = gdal.Open(self.image)
        except RuntimeError as exc:
            raise InputError(
                f"cannot open the image {self.image} ({exc}): every worker must see it under this path"
            ) from None
        values, valid = resampling.resample(ds, col, row, self.method)
        out = _to_dtype(values, self.dtype, self.nodata)
        out[:, ~valid] = self.nodata
        return out.reshape((-1, rows, cols)), int(valid.sum()), n_occluded, tile.step, tile.bound

    def _direction(self, tile):
        finite = np.flatnonzero(np.isfinite(tile.col.ravel()))
        if not finite.size:
            return None
        k = finite[finite.size // 2]
        low, high = self.dem.height_range
        return occlusion.ray_direction(self.model, tile.col.ravel()[k], tile.row.ravel()[k], low, high + 1.0)


def _reach(model, dem):
    """Degrees (longitude, latitude) an occluding ray can run from a ground point: the DEM's height range
    times the largest slope of the lines of sight at the image's corners and centre, with 20 % to spare."""
    low, high = dem.height_range
    cols, rows = model.size
    slopes = [
        occlusion.ray_direction(model, c, r, low, high + 1.0)
        for c, r in ((0, 0), (cols, 0), (0, rows), (cols, rows), (cols / 2, rows / 2))
    ]
    slopes = np.array([s for s in slopes if s is not None] or [(0.0, 0.0)])
    return tuple(1.2 * (high - low + 1.0) * np.abs(slopes).max(axis=0))


def _footprint(grid, window, reach, step):
    """lon/lat bounds of the cells of `window` (row0, col0, rows, cols) of `grid` and of the nodes of the
    coarse lattice of `step` that mapping.TileMapper lays over it (up to step - 1 cells beyond it), widened
    by `reach`."""
    row0, col0, rows, cols = window
    rows, cols = (max(-(-(n - 1) // step), 1) * step + 1 for n in (rows, cols))
    t = np.linspace(0.0, 1.0, 9)
    r = np.concatenate([row0 + t * rows, np.full(9, row0 + rows), row0 + t * rows, np.full(9, row0)]) - 0.5
    c = np.concatenate([np.full(9, col0), col0 + t * cols, np.full(9, col0 + cols), col0 + t * cols]) - 0.5
    lon, lat = grid.to_lonlat(*grid.centres(r, c))
    return (np.nanmin(lon) - reach[0], np.nanmin(lat) - reach[1], np.nanmax(lon) + reach[0], np.nanmax(lat) + reach[1])


def _ortho_tile(job, window, out):
    """Task: the output tile `window` (row0, col0, rows, cols) of the orthoimage of `job`, written to the
    GeoTIFF `out`; returns (valid cells, occluded cells, coarse step, achieved bound)."""
    (
        image,
        model,
        stored,
        grid_wkt,
        grid_geotransform,
        size,
        method,
        occlusion_on,
        dtype,
        nodata,
        max_error,
        start_step,
        reach,
        gdal_type,
    ) = job
    gdal.UseExceptions()
    grid = OutputGrid(parse_crs(grid_wkt), grid_geotransform, *size)
    dem = stored.window(_footprint(grid, window, reach, start_step))
    worker = _TileWorker(
        image,
        model,
        dem,
        TileMapper(model, dem, grid, max_error, start_step),
        method,
        occlusion_on,
        np.dtype(dtype),
        nodata,
    )
    check_cancel()  # between the stages (execution: a cancel reaches a running tile)
    values, n, hidden, step, bound = worker(window)
    check_cancel()
    row0, col0, rows, cols = window
    x0, dx, _, y0, _, dy = grid_geotransform
    with atomic_path(out, "an orthoimage tile") as tmp:
        with closing(gdal.GetDriverByName("GTiff").Create(tmp, cols, rows, values.shape[0], gdal_type)) as ds:
            ds.SetGeoTransform((x0 + col0 * dx, dx, 0.0, y0 + row0 * dy, 0.0, dy))
            ds.SetProjection(grid_wkt)
            for b in range(values.shape[0]):
                ds.GetRasterBand(b + 1).SetNoDataValue(float(nodata))
                ds.GetRasterBand(b + 1).WriteArray(values[b])
    return n, hidden, step, bound


def orthorectify(
    image: str | os.PathLike[str],
    model: Any,
    dem: Any,
    output: str | os.PathLike[str],
    grid: OutputGrid | None = None,
    settings: OrthoSettings | None = None,
    execution: Execution | None = None,
    feedback: Feedback | None = None,
) -> OrthoResult:
    """Orthoimage of raster `image` (path) with sensor `model` on `dem` (ellipsoidal heights: a dem.Dem, or a
    dem_store.StoredDem), written to GeoTIFF `output` with OrthoSettings `settings` (default: its defaults).
    The grid is `grid` (OutputGrid) or default_grid(model, dem, settings.crs, settings.cell_size); the tiles
    run on `execution` (execution.Execution; default one thread). Returns an OrthoResult; raises
    CancelledError (nothing written) when feedback cancels, ExecutionError (execution.py's)."""
    settings = settings or OrthoSettings()
    resampling_method, occlusion_mask = settings.resampling_method, settings.occlusion_mask
    start = time.perf_counter()
    if resampling_method not in resampling.METHODS:
        raise InputError(f"resampling is one of {', '.join(resampling.METHODS)}, not {resampling_method!r}")
    gdal.UseExceptions()
    try:
        ds = gdal.Open(str(image))
    except RuntimeError as exc:
        raise InputError(f"cannot open the image {image}: {exc}") from exc
    if (ds.RasterXSize, ds.RasterYSize) != tuple(model.size):
        raise InputError(
            f"the image {image} has {ds.RasterXSize} x {ds.RasterYSize} pixels but its sensor model "
            f"describes {model.size[0]} x {model.size[1]}: give the model of this image"
        )
    band = ds.GetRasterBand(1)
    np_type = np.dtype(gdal_array.GDALTypeCodeToNumericTypeCode(band.DataType))
    nodata = _nodata(band, np_type)
    grid = grid or default_grid(model, dem, settings.crs, settings.cell_size)
    progress.step(
        feedback,
        0,
        f"orthoimage grid {grid.cols} x {grid.rows} cells of {grid.geotransform[1]:g} "
        f"({grid.srs.GetName()}), {resampling_method} resampling",
    )
    windows = [(y0, x0, y1 - y0, x1 - x0) for x0, y0, x1, y1 in tile_grid((grid.cols, grid.rows), settings.tile)]
    reach = _reach(model, dem) if occlusion_mask else (0.0, 0.0)
    with work_dir(output, "the orthoimage tiles") as work:
        dem = as_stored(dem, work)
        job = (
            str(image),
            model,
            dem,
            grid.srs.ExportToWkt(),
            tuple(grid.geotransform),
            (grid.cols, grid.rows),
            resampling_method,
            occlusion_mask,
            np_type.str,
            nodata,
            settings.max_error,
            settings.start_step,
            reach,
            band.DataType,
        )
        tiles = [os.path.join(work, f"tile-{k:05d}.tif") for k in range(len(windows))]
        done = run_tasks(
            _ortho_tile,
            [(job, w, t) for w, t in zip(windows, tiles)],
            execution,
            progress.scaled(feedback, 0, 90),
            "the orthoimage tiles",
        )
        steps: dict[int, int] = {}
        for _, _, step, _ in done:
            steps[step] = steps.get(step, 0) + 1
        with raster_output(output, settings.cog, progress.scaled(feedback, 95, 100) if settings.cog else None) as tmp:
            assemble_tiles(
                tiles,
                tmp,
                Frame(grid.geotransform, (grid.cols, grid.rows), grid.srs),
                CREATION_OPTIONS,
                overviews=settings.overviews,
                feedback=progress.scaled(feedback, 90, 95 if settings.cog else 100),
            )
    result = OrthoResult(
        str(output),
        grid,
        max((d[3] for d in done), default=0.0),
        steps,
        sum(d[0] for d in done),
        sum(d[1] for d in done),
        time.perf_counter() - start,
    )
    progress.step(feedback, 100, result.summary())
    return result
