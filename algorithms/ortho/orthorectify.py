"""Orthoimage by the indirect method (Heipke et al. 1992, section 4.1): for every output cell its ground point
(x, y; h from the DEM) is mapped into the image with any sensor model (mapping.py: coarse grid with a stated
error bound) and the image is resampled there (resampling.py). On a DSM this is a true orthoimage (roofs and
canopy in their place): the cells the surface hides from the image (occlusion.py) show the occluder's image
values, so they are flagged in an occlusion mask, and can be made nodata. The step's entry point is
steps/orthoimage.py's orthorectify_image.

The output is processed in square tiles (tiling.tile_grid), each a task on the chosen execution
(execution.run_tasks: threads, local processes or Dask). Per tile only the image window it needs is
read (GDAL) and only the DEM window under the tile's footprint, widened by the reach of an occluding
ray (the DEM's height range times the slope of the lines of sight), is taken from the DEM, which the
step reads from its stored file (dem_store.StoredDem.window; a DEM in memory is stored in a work folder beside
the output first). So memory follows the tile and the number of workers, and the result does not depend on the
execution. Each task writes its tile as a GeoTIFF (and its mask tile); GDAL assembles them (a VRT translated into a
tiled, DEFLATE-compressed GeoTIFF of the image's data type with nodata set and overviews, geotiff.assemble_tiles)
under temporary names renamed at the end, once both are written (a cancel leaves no file)."""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from osgeo import gdal, gdal_array

from .. import progress
from ..atomic import atomic_path, closing, work_dir
from ..crs import srs as parse_crs
from ..dem_store import as_stored
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..progress import Feedback
from ..surface.geotiff import CODE_OPTIONS, Frame, assemble_tiles, raster_outputs
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
    is given: default_grid), `resampling_method` 'bilinear' or 'bicubic', `occluded_nodata` (occluded cells
    as nodata), `max_error` (px: the bound of the coarse-grid interpolation, mapping.py) from the coarse
    step `start_step`, output tiles of `tile` cells a side, internal `overviews`, a Cloud-Optimised GeoTIFF
    where `cog`."""

    crs: str | None = None
    cell_size: float | None = None
    resampling_method: str = "bilinear"
    occluded_nodata: bool = False
    max_error: float = 0.01
    start_step: int = START_STEP
    tile: int = TILE
    overviews: bool = True
    cog: bool = False


@dataclass(frozen=True)
class OrthoOutputs:
    """Where `orthorectify` writes: the orthoimage `image`, and the occlusion mask `occlusions` (None, or an empty
    path: none)."""

    image: str | os.PathLike[str]
    occlusions: str | os.PathLike[str] | None = None


@dataclass
class OrthoResult:
    """What orthorectify wrote: `path`, `grid`, `bound` (largest achieved coarse-grid error bound, px),
    `steps` ({coarse step: tiles}), `cells` (valid cells written), `occluded` (cells of the image hidden by the
    surface, where occlusion was computed), `seconds`, `occlusions` (the occlusion mask's path, or None)."""

    path: str
    grid: OutputGrid
    bound: float
    steps: dict[int, int]
    cells: int
    occluded: int
    seconds: float
    occlusions: str | None = None

    def summary(self) -> str:
        steps = ", ".join(f"{n} x step {s}" for s, n in sorted(self.steps.items(), reverse=True))
        return (
            f"{self.grid.cols} x {self.grid.rows} cells, {self.cells} with image values, {self.occluded} "
            f"occluded; coarse-grid tiles: {steps}; achieved interpolation bound {self.bound:.2g} px; "
            f"{self.seconds:.1f} s"
        )


def _nodata(band: Any, dtype: np.dtype) -> float:
    """The image's nodata value, else 0 for integer images (DIMAP's DN 0) and NaN for floats."""
    value = band.GetNoDataValue()
    if value is not None:
        return value
    return 0 if np.issubdtype(dtype, np.integer) else math.nan


def _is_nodata(values: np.ndarray, nodata: float) -> np.ndarray:
    """Where `values` are the nodata value `nodata` (NaN: where they are not finite)."""
    return ~np.isfinite(values) if math.isnan(nodata) else values == nodata


def _to_dtype(values: np.ndarray, dtype: np.dtype, nodata: float) -> np.ndarray:
    """Resampled values rounded and clipped to `dtype`, never equal to an integer nodata at its range's end."""
    if not np.issubdtype(dtype, np.integer):
        return values.astype(dtype)
    info = np.iinfo(dtype)
    lo = info.min + 1 if nodata == info.min else info.min
    hi = info.max - 1 if nodata == info.max else info.max
    return np.clip(np.rint(values), lo, hi).astype(dtype)


#: codes of the occlusion mask: the cell is seen by the image, hidden from it by the surface, or has no
#: image value (outside the image or without a DEM height: the mask's nodata)
SEEN, OCCLUDED, OUTSIDE = 0, 1, 255


class _TileWorker:
    """Computes one output tile: mapping, occlusion, resampling (one GDAL handle per call: thread-safe)."""

    def __init__(self, job: _OrthoJob, dem: Any, mapper: TileMapper) -> None:
        self.job, self.dem, self.mapper = job, dem, mapper

    def __call__(self, window: tuple[int, int, int, int]) -> _Tile:
        job = self.job
        row0, col0, rows, cols = window
        tile = self.mapper.tile(row0, col0, rows, cols)
        col, row = tile.col.ravel(), tile.row.ravel()
        hidden = None
        if job.occluded_nodata or job.mask:
            direction = self._direction(tile)
            hidden = np.zeros(col.size, np.bool_)
            if direction is not None:
                hidden = occlusion.occluded(self.dem, tile.lon.ravel(), tile.lat.ravel(), tile.h.ravel(), direction)
        try:
            ds = gdal.Open(job.image)
        except RuntimeError as exc:
            raise InputError(
                f"cannot open the image {job.image} ({exc}): every worker must see it under this path"
            ) from None
        values, inside = resampling.resample(ds, col, row, job.method)
        out = _to_dtype(values, np.dtype(job.dtype), job.nodata)
        inside &= ~_is_nodata(out, job.nodata).all(axis=0)  # the image's own nodata resampled: no value either
        occluded = inside & hidden if hidden is not None else np.zeros(col.size, np.bool_)
        valid = inside & ~occluded if job.occluded_nodata else inside
        out[:, ~valid] = job.nodata
        codes = None
        if job.mask:
            codes = np.where(inside, np.where(occluded, OCCLUDED, SEEN), OUTSIDE).astype(np.uint8).reshape(rows, cols)
        return _Tile(out.reshape((-1, rows, cols)), codes, int(valid.sum()), int(occluded.sum()), tile.step, tile.bound)

    def _direction(self, tile: Any) -> tuple[float, float] | None:
        finite = np.flatnonzero(np.isfinite(tile.col.ravel()))
        if not finite.size:
            return None
        k = finite[finite.size // 2]
        low, high = self.dem.height_range
        return occlusion.ray_direction(self.job.model, tile.col.ravel()[k], tile.row.ravel()[k], low, high + 1.0)


def _reach(model: Any, dem: Any) -> tuple[float, float]:
    """Degrees (longitude, latitude) an occluding ray can run from a ground point: the DEM's height range
    times the largest slope of the lines of sight at the image's corners and centre, with 20 % to spare."""
    low, high = dem.height_range
    cols, rows = model.size
    found = [
        occlusion.ray_direction(model, c, r, low, high + 1.0)
        for c, r in ((0, 0), (cols, 0), (0, rows), (cols, rows), (cols / 2, rows / 2))
    ]
    slopes = np.array([s for s in found if s is not None] or [(0.0, 0.0)])
    dlon, dlat = 1.2 * (high - low + 1.0) * np.abs(slopes).max(axis=0)
    return float(dlon), float(dlat)


def _footprint(
    grid: OutputGrid, window: tuple[int, int, int, int], reach: tuple[float, float], step: int
) -> tuple[float, float, float, float]:
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


@dataclass(frozen=True)
class _OrthoJob:
    """What every tile task of one orthoimage shares (picklable: it travels to worker processes and Dask): the
    `image` path and its sensor `model`, the `stored` DEM (dem_store.StoredDem), the output grid (`grid_wkt`,
    `geotransform`, `size` cols x rows), the resampling `method`, `occluded_nodata` (occluded cells as nodata),
    `mask` (the occlusion mask is written), the image's numpy `dtype` (its str), `nodata` and GDAL type
    `gdal_type`, the coarse-grid `max_error` from `start_step`, and the occluding rays' `reach` (degrees)."""

    image: str
    model: Any
    stored: Any
    grid_wkt: str
    geotransform: tuple[float, ...]
    size: tuple[int, int]
    method: str
    occluded_nodata: bool
    mask: bool
    dtype: str
    nodata: float
    gdal_type: int
    max_error: float
    start_step: int
    reach: tuple[float, float]


class _Tile(NamedTuple):
    """One computed output tile: image `values` (bands, rows, cols), occlusion `codes` (rows, cols; None
    where no mask is asked for), its `valid` and `occluded` cell counts, coarse `step` and achieved `bound`."""

    values: np.ndarray
    codes: np.ndarray | None
    valid: int
    occluded: int
    step: int
    bound: float


def _write_tile(
    path: str, values: np.ndarray, job: _OrthoJob, window: tuple[int, int, int, int], gdal_type: int, nodata: float
) -> None:
    """`values` (bands, rows, cols) as the GeoTIFF tile `path` of `window` (row0, col0, rows, cols) of the grid."""
    row0, col0, rows, cols = window
    x0, dx, _, y0, _, dy = job.geotransform
    with atomic_path(path, "an orthoimage tile") as tmp:
        with closing(gdal.GetDriverByName("GTiff").Create(tmp, cols, rows, values.shape[0], gdal_type)) as ds:
            ds.SetGeoTransform((x0 + col0 * dx, dx, 0.0, y0 + row0 * dy, 0.0, dy))
            ds.SetProjection(job.grid_wkt)
            for b in range(values.shape[0]):
                ds.GetRasterBand(b + 1).SetNoDataValue(float(nodata))
                ds.GetRasterBand(b + 1).WriteArray(values[b])


def _ortho_tile(
    job: _OrthoJob, window: tuple[int, int, int, int], out: str, mask_out: str | None
) -> tuple[int, int, int, float]:
    """Task: the output tile `window` (row0, col0, rows, cols) of the orthoimage of `job`, written to the
    GeoTIFF `out` (and its occlusion codes to `mask_out` where the job asks for the mask); returns (valid
    cells, occluded cells, coarse step, achieved bound)."""
    gdal.UseExceptions()
    grid = OutputGrid(parse_crs(job.grid_wkt), job.geotransform, *job.size)
    dem = job.stored.window(_footprint(grid, window, job.reach, job.start_step))
    worker = _TileWorker(job, dem, TileMapper(job.model, dem, grid, job.max_error, job.start_step))
    check_cancel()  # between the stages (execution: a cancel reaches a running tile)
    tile = worker(window)
    check_cancel()
    _write_tile(out, tile.values, job, window, job.gdal_type, job.nodata)
    if mask_out is not None and tile.codes is not None:
        _write_tile(mask_out, tile.codes[None], job, window, gdal.GDT_Byte, OUTSIDE)
    return tile.valid, tile.occluded, tile.step, tile.bound


def orthorectify(
    image: str | os.PathLike[str],
    model: Any,
    dem: Any,
    output: str | os.PathLike[str] | OrthoOutputs,
    grid: OutputGrid | None = None,
    settings: OrthoSettings | None = None,
    execution: Execution | None = None,
    feedback: Feedback | None = None,
) -> OrthoResult:
    """Orthoimage of raster `image` (path) with sensor `model` on `dem` (ellipsoidal heights: a dem.Dem, or a
    dem_store.StoredDem), written to the GeoTIFF `output` (a path, or OrthoOutputs) with OrthoSettings `settings`
    (default: its defaults). The grid is `grid` (OutputGrid) or default_grid(model, dem, settings.crs,
    settings.cell_size); the tiles run on `execution` (execution.Execution; default one thread). Where the outputs
    name the occlusions, the occlusion mask is written there too (Byte: SEEN 0, OCCLUDED 1 by the DEM's surface,
    OUTSIDE 255 where the orthoimage has no value: outside the image or the DEM, or the image's nodata; its nodata),
    whether or not occluded cells are nodata in the image; both are renamed once both are written. Returns an
    OrthoResult; raises CancelledError (nothing written) when feedback cancels, ExecutionError (execution.py's)."""
    settings = settings or OrthoSettings()
    resampling_method = settings.resampling_method
    outputs = output if isinstance(output, OrthoOutputs) else OrthoOutputs(output)
    output, occlusions = outputs.image, outputs.occlusions or None
    start = time.perf_counter()
    if occlusions is not None and os.path.abspath(occlusions) == os.path.abspath(output):
        raise InputError(f"the occlusion mask and the orthoimage are both {output}: give the mask another name")
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
    occlusion_on = settings.occluded_nodata or occlusions is not None
    reach = _reach(model, dem) if occlusion_on else (0.0, 0.0)
    with work_dir(output, "the orthoimage tiles") as work:
        dem = as_stored(dem, work)
        job = _OrthoJob(
            str(image),
            model,
            dem,
            grid.srs.ExportToWkt(),
            tuple(grid.geotransform),
            (grid.cols, grid.rows),
            resampling_method,
            settings.occluded_nodata,
            occlusions is not None,
            np_type.str,
            nodata,
            band.DataType,
            settings.max_error,
            settings.start_step,
            reach,
        )
        tiles = [os.path.join(work, f"tile-{k:05d}.tif") for k in range(len(windows))]
        masks = [
            os.path.join(work, f"mask-{k:05d}.tif") if occlusions is not None else None for k in range(len(windows))
        ]
        done = run_tasks(
            _ortho_tile,
            [(job, w, t, m) for w, t, m in zip(windows, tiles, masks)],
            execution,
            progress.scaled(feedback, 0, 90),
            "the orthoimage tiles",
        )
        steps: dict[int, int] = {}
        for _, _, step, _ in done:
            steps[step] = steps.get(step, 0) + 1
        frame = Frame(grid.geotransform, (grid.cols, grid.rows), grid.srs)
        cog = progress.scaled(feedback, 95, 100) if settings.cog else None
        with raster_outputs([str(output), str(occlusions) if occlusions is not None else None], settings.cog, cog) as (
            tmp,
            mask_tmp,
        ):
            assemble_tiles(
                tiles,
                tmp,  # type: ignore[arg-type]
                frame,
                CREATION_OPTIONS,
                overviews="AVERAGE" if settings.overviews else None,
                feedback=progress.scaled(feedback, 90, 93 if mask_tmp else 95 if settings.cog else 100),
            )
            if mask_tmp:
                assemble_tiles(
                    masks,  # type: ignore[arg-type]
                    mask_tmp,
                    frame,
                    CODE_OPTIONS,
                    description="occlusion mask: 0 seen, 1 occluded by the surface, 255 no value",
                    overviews="NEAREST" if settings.overviews else None,  # no average of codes
                    feedback=progress.scaled(feedback, 93, 95 if settings.cog else 100),
                )
    result = OrthoResult(
        str(output),
        grid,
        max((d[3] for d in done), default=0.0),
        steps,
        sum(d[0] for d in done),
        sum(d[1] for d in done),
        time.perf_counter() - start,
        str(occlusions) if occlusions is not None else None,
    )
    progress.step(feedback, 100, result.summary())
    return result
