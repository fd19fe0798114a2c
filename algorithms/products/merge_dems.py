"""Several DEMs (pairs, blocks, dates) merged into one (pushbroom:mergedems), with its precision and count rasters.

1. Co-registration (optional, on by default): every DEM but the first is co-registered to the first, or every DEM
   to a reference (quality.coregistration, Nuth and Kääb 2011: the shift, and the tilt where asked); where the
   terrain does not show the horizontal shift, the vertical offset alone, with a warning. The co-registered DEMs are
   written to a work folder (quality.coregister_dem.write_coregistered), their precision rasters moved with them.
2. The output grid: the first DEM's CRS and cell (or those given), the cells of the first DEM's lattice whose
   centres lie inside the union of the DEMs. A DEM of another cell size or CRS is resampled onto it (the average of
   its cells inside a cell where it is finer, bilinear otherwise; its precision likewise), and the log says so.
3. Per cell, over the DEMs that have a height there (h_i, with the precision sigma_i of its precision raster, or 1
   where no DEM has one):
   - outliers: with three or more heights, a height farther from their median m than K sqrt(s^2 + sigma_i^2) is left
     out, s = 1.4826 median |h_i - m| their robust spread (two heights cannot tell which is wrong: both stay);
   - the weighted mean h = sum(w_i h_i) / sum(w_i), w_i = t_i / sigma_i^2: inverse variance, times a taper
     t_i = min((d_i / (BLEND + 1))^2, 1) of the cell's distance d_i (cells) to the DEM's own edge (where its valid
     cells end), so that a DEM's edge leaves no step where its heights differ from the others' by their errors
     (squared: the mean's share of an ending DEM falls off nearly linearly, where a linear taper leaves a third of
     the difference as one step at the edge: docs/validation.md#merge-dems);
   - its standard error, that of a weighted mean of independent heights: sqrt(sum(w_i^2 sigma_i^2)) / sum(w_i);
   - the count of the heights used.
   DEMs of one image block share errors (a triplet's pairs share images): the standard error then is a floor
   (docs/validation.md#merge-dems measures it).
4. Tiles of TILE cells, each with BLEND cells more around (the taper sees a DEM's edge up to BLEND cells away), each a
   task on the chosen execution that resamples every DEM's window onto it; GDAL assembles them. Memory follows the
   tile and the number of DEMs, not the area.

Failure modes: InputError (fewer than two DEMs, a precision raster per DEM or none, a DEM that does not overlap the
one it is co-registered to, a vertical datum a CRS contradicts), CoregistrationError, CancelledError."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from osgeo import gdal
from scipy import ndimage

from .. import progress
from ..atomic import work_dir
from ..crs import srs as parse_crs
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..progress import Feedback
from ..quality.coregister_dem import write_coregistered
from ..quality.coregistration import CoregParams, CoregResult, coregister_or_vertical
from ..quality.height_differences import Reference, check_stated
from ..quality.rasters import SAME_CELL, Grid, cell_metres, mean_cell, open_raster, raster_srs, resampling_for, warp_to
from ..stats import NMAD_SCALE
from ..surface.geotiff import Frame, assemble_tiles, raster_outputs, write_float_raster
from ..task_runtime import check_cancel
from ..tiling import tile_grid

#: cells per side of a tile
TILE = 1024


@dataclass(frozen=True)
class MergeParams:
    """pushbroom:mergedems' settings."""

    dems: tuple[str, ...]
    precisions: tuple[str, ...] = ()  # one precision raster per DEM, in their order, or none
    heights: str = "ellipsoidal"  # of every DEM (control_points.HEIGHT_TYPES)
    coregister: bool = True
    reference: str | None = None  # co-register to it (else to the first DEM)
    reference_heights: str = "ellipsoidal"
    tilt: bool = False  # co-register with a tilt
    crs: str | None = None  # output CRS; None: the first DEM's
    cell: float | None = None  # output cell in CRS units; None: the first DEM's
    outlier_k: float = 3.0  # K of the outlier test
    blend: int = 10  # BLEND: cells over which a DEM's weight rises from its edge
    execution: Execution = field(default_factory=Execution)
    cog: bool = False

    def check(self) -> MergeParams:
        if len(self.dems) < 2:
            raise InputError("give two DEMs or more to merge")
        if self.precisions and len(self.precisions) != len(self.dems):
            raise InputError(
                f"give one precision raster per DEM ({len(self.dems)} DEMs, {len(self.precisions)} precision "
                "rasters), or none"
            )
        if not self.outlier_k > 0 or self.blend < 0 or (self.cell is not None and not self.cell > 0):
            raise InputError("the outlier bound and the cell size must be positive and the blend width not negative")
        self.execution.check()
        return self


@dataclass(frozen=True)
class MergeOutputs:
    dem: str
    precision: str | None = None
    count: str | None = None


@dataclass
class MergeResult:
    """What merge_dems did: the co-registration of each DEM (None: the one the others are co-registered to, or no
    co-registration), the cells with a height, and per count of heights used its cells; the outliers left out."""

    outputs: MergeOutputs
    shifts: list[CoregResult | None]
    cells: int = 0
    counts: dict[int, int] = field(default_factory=dict)
    outliers: int = 0


@dataclass(frozen=True)
class _Input:
    """A DEM as the tiles read it: its raster (co-registered where it was) and its precision raster or None."""

    dem: str
    precision: str | None


@dataclass(frozen=True)
class _Job:
    inputs: tuple[_Input, ...]
    frame: tuple[tuple[float, ...], tuple[int, int], str]  # the output's geotransform, (cols, rows), CRS WKT
    outlier_k: float
    blend: int
    weighted: bool  # the inputs have precision rasters


def merge_tile(job: _Job, box: tuple[int, int, int, int], paths: tuple[str | None, ...]) -> dict[str, Any]:
    """Task: the merged heights, standard errors and counts of the output cells `box` (module docstring), written as
    GeoTIFF tiles to `paths` (heights, precision, count; None: an output not asked for); returns the tile's counts
    and outliers."""
    gt, _, wkt = job.frame
    c0, r0, c1, r1 = box
    m = job.blend
    wide = Grid(
        np.empty((r1 - r0 + 2 * m, c1 - c0 + 2 * m)),
        (gt[0] + (c0 - m) * gt[1], gt[1], 0.0, gt[3] + (r0 - m) * gt[5], 0.0, gt[5]),
        parse_crs(wkt),
    )
    cell = math.sqrt(np.prod(wide.cell_metres()))
    heights, sigmas, tapers = [], [], []
    for item in job.inputs:
        check_cancel()
        source = open_raster(item.dem, "DEM")
        h = warp_to(source, wide, resampling_for(source, cell))
        valid = np.isfinite(h)
        if not valid.any():
            continue
        sigma = np.ones_like(h)
        if item.precision:
            precision = open_raster(item.precision, "precision raster")
            sigma = warp_to(precision, wide, resampling_for(precision, cell))
            valid &= np.isfinite(sigma) & (sigma > 0)
        distance = ndimage.distance_transform_edt(np.pad(valid, 1))[1:-1, 1:-1]
        heights.append(np.where(valid, h, np.nan))
        sigmas.append(sigma)
        tapers.append(np.minimum((distance / (m + 1)) ** 2, 1.0))
    inner = (slice(m, m + r1 - r0), slice(m, m + c1 - c0))
    shape = (r1 - r0, c1 - c0)
    if not heights:
        merged, se, count, outliers = np.full(shape, np.nan), np.full(shape, np.nan), np.zeros(shape), 0
    else:
        h, s, t = (np.stack([a[inner] for a in arrays]) for arrays in (heights, sigmas, tapers))
        merged, se, count, outliers = _merge(h, s, t, job.outlier_k)
        if not job.weighted:
            se = np.full(shape, np.nan)
    tile_gt = (wide.geotransform[0] + m * gt[1], gt[1], 0.0, wide.geotransform[3] + m * gt[5], 0.0, gt[5])
    check_cancel()
    for path, values in zip(paths, (merged, se, np.where(count > 0, count, np.nan))):
        if path:
            write_float_raster(path, values, tile_gt, wide.srs, overviews=False)
    used = count[count > 0].astype(int)
    return {"counts": np.bincount(used).tolist() if used.size else [], "outliers": outliers}


def _merge(h: np.ndarray, s: np.ndarray, t: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(heights, standard errors, counts, outliers left out) of the stacked inputs (n, rows, cols): heights h (NaN:
    none), sigmas s, tapers t (module docstring)."""
    valid = np.isfinite(h)
    n = valid.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        median = _median(h, n)
        spread = NMAD_SCALE * _median(np.abs(h - median), n)
        outlier = valid & (n >= 3) & (np.abs(h - median) > k * np.sqrt(spread**2 + s**2))
        use = valid & ~outlier
        w = np.where(use, t / s**2, 0.0)
        total = w.sum(axis=0)
        merged = np.where(total > 0, np.nansum(np.where(use, w * h, 0.0), axis=0) / total, np.nan)
        se = np.where(total > 0, np.sqrt((w**2 * np.where(use, s, 0.0) ** 2).sum(axis=0)) / total, np.nan)
    return merged, se, use.sum(axis=0).astype(float), int(outlier.sum())


def _median(values: np.ndarray, n: np.ndarray) -> np.ndarray:
    """The median over axis 0 of `values` (NaN: none) whose finite ones number `n` per cell; NaN where none (the
    sort puts NaN last: no warning from an all-NaN cell, as numpy's nanmedian gives)."""
    ordered = np.sort(values, axis=0)
    low = np.take_along_axis(ordered, np.maximum((n - 1) // 2, 0)[None], axis=0)[0]
    high = np.take_along_axis(ordered, np.maximum(n // 2, 0).clip(max=len(values) - 1)[None], axis=0)[0]
    return np.where(n > 0, 0.5 * (low + high), np.nan)


def _coregistered(
    params: MergeParams, work: str, feedback: Feedback | None
) -> tuple[list[_Input], list[CoregResult | None]]:
    """The inputs as the tiles read them, each DEM co-registered where asked (module docstring), and the
    co-registrations."""
    precisions: list[str | None] = list(params.precisions) or [None] * len(params.dems)
    if not params.coregister:
        return [_Input(d, p) for d, p in zip(params.dems, precisions)], [None] * len(params.dems)
    if params.reference:
        reference, first = Reference(params.reference, params.reference_heights), 0
    else:
        reference, first = Reference(params.dems[0], params.heights), 1
    inputs: list[_Input] = [_Input(params.dems[0], precisions[0])] if first else []
    shifts: list[CoregResult | None] = [None] * first
    coreg = CoregParams(
        dem_heights=params.heights,
        reference_heights=reference.datum,
        tilt=params.tilt,
        execution=params.execution,
    )
    todo = list(range(first, len(params.dems)))
    for j, i in enumerate(todo):
        span = progress.scaled(feedback, 100.0 * j / len(todo), 100.0 * (j + 1) / len(todo))
        dem = params.dems[i]
        try:
            result = coregister_or_vertical(dem, reference, coreg, progress.scaled(span, 0, 80))
        except InputError as exc:
            raise InputError(
                f"the DEM {dem} cannot be co-registered to {reference.path}: {exc}. Co-register to a reference that "
                "covers every DEM, or merge without co-registration"
            ) from None
        progress.ensure(feedback).pushInfo(f"{dem}: co-registered, {result.shift.describe(result.cell)}")
        moved = os.path.join(work, f"dem-{i:03d}.tif")
        write_coregistered(dem, result.shift, result.units, moved, coreg.execution, progress.scaled(span, 80, 100))
        precision = precisions[i]
        if precision:  # moved with its DEM: a VRT of it on the moved grid
            precision = _moved_vrt(precision, result, os.path.join(work, f"precision-{i:03d}.vrt"))
        inputs.append(_Input(moved, precision))
        shifts.append(result)
    return inputs, shifts


def _moved_vrt(path: str, result: CoregResult, vrt: str) -> str:
    """A VRT of the raster at `path` with its grid moved by `result`'s horizontal shift (values as they are)."""
    ds = gdal.Translate(vrt, open_raster(path, "precision raster"), format="VRT")
    ds.SetGeoTransform(result.shift.moved(ds.GetGeoTransform(), result.units))
    ds = None
    return vrt


def _output_frame(params: MergeParams, inputs: list[_Input], feedback: Feedback | None) -> tuple:
    """(geotransform, (cols, rows), CRS WKT) of the output grid (module docstring); says which DEMs are resampled."""
    first = open_raster(inputs[0].dem, "DEM")
    target = parse_crs(params.crs) if params.crs else raster_srs(first)
    # the lattice: the first DEM's own, or (another CRS) the first DEM's as GDAL warps it there, in the target's units
    gt0 = first.GetGeoTransform() if not params.crs else _warped(first, target).GetGeoTransform()
    dx = params.cell if params.cell else gt0[1]
    dy = params.cell if params.cell else -gt0[5]
    xs, ys = [], []
    for item in inputs:
        ds = open_raster(item.dem, "DEM")
        warped = _warped(ds, target)
        g, cols, rows = warped.GetGeoTransform(), warped.RasterXSize, warped.RasterYSize
        xs += [g[0], g[0] + cols * g[1]]
        ys += [g[3], g[3] + rows * g[5]]
        own = mean_cell(ds)
        out = math.sqrt(np.prod(cell_metres((0, dx, 0, g[3], 0, -dy), target, 1)))
        if abs(own - out) > SAME_CELL * out:
            progress.warn(
                feedback,
                f"{item.dem} has cells of {own:.3g} m: resampled onto the merge's {out:.3g} m cells "
                f"({'their average' if own < out else 'bilinear'})",
            )
    # the cells of the first DEM's lattice whose centres lie inside the DEMs' union
    x0 = gt0[0] + math.floor((min(xs) - gt0[0]) / dx + 0.5) * dx
    y0 = gt0[3] - math.floor((gt0[3] - max(ys)) / dy + 0.5) * dy
    cols = int(math.ceil((max(xs) - x0) / dx - 0.5))
    rows = int(math.ceil((y0 - min(ys)) / dy - 0.5))
    return (x0, dx, 0.0, y0, 0.0, -dy), (cols, rows), target.ExportToWkt()


def _warped(ds: Any, target: Any) -> Any:
    """A VRT of the raster `ds` warped to the CRS `target` (GDAL's choice of grid, the exact transformation)."""
    return gdal.Warp("", ds, format="VRT", dstSRS=target.ExportToWkt(), errorThreshold=0)


def _check_pairs(params: MergeParams) -> None:
    """InputError where a precision raster does not lie on its DEM's grid (they pair by their order)."""
    for dem, precision in zip(params.dems, params.precisions):
        a, b = open_raster(dem, "DEM"), open_raster(precision, "precision raster")
        same = (a.RasterXSize, a.RasterYSize) == (b.RasterXSize, b.RasterYSize) and np.allclose(
            a.GetGeoTransform(), b.GetGeoTransform(), rtol=0, atol=1e-9 * max(abs(a.GetGeoTransform()[1]), 1e-12)
        )
        if not same or not raster_srs(a).IsSame(raster_srs(b)):
            raise InputError(
                f"the precision raster {precision} does not lie on the grid of the DEM {dem}: the DEMs and their "
                "precision rasters pair in the order they are given, each on its DEM's cells"
            )


def merge_dems(params: MergeParams, outputs: MergeOutputs, feedback: Feedback | None = None) -> MergeResult:
    """Merge the DEMs of `params` into `outputs` (module docstring); returns a MergeResult."""
    params = params.check()
    if outputs.precision and not params.precisions:
        raise InputError("the merged precision raster needs the DEMs' precision rasters: give one per DEM")
    for path in params.dems:
        check_stated(open_raster(path, "DEM"), params.heights, "DEM", path)
    _check_pairs(params)
    with work_dir(outputs.dem, "the merge's tiles") as work:
        inputs, shifts = _coregistered(params, work, progress.scaled(feedback, 0, 40))
        frame = _output_frame(params, inputs, feedback)
        job = _Job(tuple(inputs), frame, params.outlier_k, params.blend, bool(params.precisions))
        boxes = tile_grid(frame[1], TILE)
        wanted = zip(("h", "se", "n"), (outputs.dem, outputs.precision, outputs.count))
        kinds = [kind if path else None for kind, path in wanted]
        names = [
            tuple(os.path.join(work, f"{kind}-{k:05d}.tif") if kind else None for kind in kinds)
            for k in range(len(boxes))
        ]
        done = run_tasks(
            merge_tile,
            list(zip([job] * len(boxes), boxes, names)),
            params.execution,
            progress.scaled(feedback, 40, 90),
            "merge tiles",
        )
        result = MergeResult(outputs, shifts)
        for d in done:
            for k, c in enumerate(d["counts"]):
                result.counts[k] = result.counts.get(k, 0) + c
            result.outliers += d["outliers"]
        result.cells = sum(c for k, c in result.counts.items() if k > 0)
        if not result.cells:
            raise InputError("the DEMs hold no height on the merge's grid: check their CRS and nodata")
        _write(
            outputs,
            names,
            Frame(frame[0], frame[1], parse_crs(frame[2])),
            params.cog,
            progress.scaled(feedback, 90, 100),
        )
    progress.ensure(feedback).pushInfo(
        f"merged {len(params.dems)} DEMs: {result.cells} cells with a height; "
        + ", ".join(f"{result.counts.get(k, 0)} from {k}" for k in sorted(result.counts) if k)
        + f"; {result.outliers} outlying heights left out"
    )
    return result


def _write(
    outputs: MergeOutputs, names: list[tuple[str | None, ...]], frame: Frame, cog: bool, feedback: Feedback | None
) -> None:
    """The outputs asked for, from the tiles: all renamed at the end, or none."""
    wanted = [
        (0, "merged height (m)"),
        (1, "standard error of the merged height (m)"),
        (2, "heights merged in the cell"),
    ]
    with raster_outputs([outputs.dem, outputs.precision, outputs.count], cog) as temps:
        for tmp, (k, description) in zip(temps, wanted):
            if tmp:
                tiles = [n[k] for n in names]
                assemble_tiles(tiles, tmp, frame, description=description, feedback=feedback)  # type: ignore[arg-type]
