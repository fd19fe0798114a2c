"""The DEM step (pushbroom:interpolatedem) on tiles: a point cloud of any size interpolated with
tin_dem.surface_on_grid tile by tile, on the chosen execution (execution.run_tasks), and assembled
into one tiled GeoTIFF with overviews. Memory follows the tile and the number of workers, not the
cloud.

1. The cloud is read in chunks (point_input.point_chunks) twice: for its centre (the UTM zone of the
   output CRS, as tin_dem.interpolate_dem chooses it), then to transform it to the output CRS, keep
   its bounds (the grid: tin_grid.Grid.covering) and mark the points tin_dem.default_max_edge samples
   (the same sample as the whole cloud's). Each chunk goes to a work folder beside the output.
2. The grid is cut into tiles of `tile` x `tile` cells (tiling.tile_grid). Each point goes to every
   tile whose box, widened by a margin, holds it. The margin is MARGIN_EDGES maximum triangle edges
   (the given one, or an upper bound from the point density: the mean spacing of points spread over
   their bounding box is no smaller than their median nearest-neighbour distance), so that the
   Delaunay triangles, the blunder filter's neighbourhoods and the gap rule of the tile's own cells
   are those of the whole cloud: tile borders leave no seam.
3. Without a given maximum edge, a first round of tasks measures the sampled points' nearest-neighbour
   distances, each tile those in its own cells; the median gives default_max_edge. Should it exceed
   the margin's assumption, the points are bucketed again with a wider margin.
4. The blunder filter's spread (tin.spread: the median and robust sigma of the residuals) is that of
   the whole cloud, as a single TIN would take it: per filter iteration, a round of tasks returns each
   tile's residual histogram (tin.residual_histogram) of the points it owns after the iterations
   already decided, and their sum gives the iteration's spread. The rounds end when no point lies
   beyond k sigmas.
5. Each tile is a task: surface_on_grid on the tile's cells with its points, the breaklines and the
   spreads, written as a GeoTIFF tile.
6. A VRT of the tiles is translated into the output GeoTIFF (geotiff.OPTIONS) and its overviews are
   built from it, all by GDAL in blocks; the precision raster likewise. Tiles without points are gaps.

Method "cells" (dense points): each point goes to every tile within DemParams.radius cells of its own cell
(a margin of radius + 1/2 cells; ownership by cell), and each tile is one task of cell_dem.cells_on_grid
(per-cell medians after the per-cell outlier test, k = DemParams.k; a cell uses its best tier of points: the
refined three-ray points, then the refined two-ray ones, and the unrefined dense ones only with
DemParams.fallback; an empty cell the points of the cells within the radius; with the points' sigma_h, a cell's own
refined points before the ring's better tier where they are no less precise); steps 3 and 4 do not apply.
Besides the precision raster it can write the count of points per cell, and a mask raster of what each cell
is: its own points' median, its neighbours', filled, or a gap (gap_fill.py). With DemParams.fill, the gaps
within that many cells of measured ones are filled, and the mask is always written (by default beside the
DEM): filling is never silent.

Failure modes: tin_dem's InputErrors (settings, no CRS, points outside the output CRS or an output CRS far
from them, no defined cell), a cell size that leaves the DEM fewer than 2 cells along an axis
(crs.check_grid_cells), ExecutionError from the execution, CancelledError; nothing is left under an output name
(atomic.atomic_path) and the work folder is removed (atomic.work_dir)."""

import math
import os
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .. import histogram, progress
from ..atomic import append_bytes, save_array, work_dir
from ..crs import check_grid_cells, srs as parse_crs, transform
from ..errors import CancelledError, InputError
from ..execution import run_tasks, session
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .cell_dem import CellSettings, cells_on_grid, point_tiers
from .gap_fill import fill_gaps
from .geotiff import Frame, assemble_tiles, raster_outputs, write_float_raster
from .point_input import PointSet, point_chunks, read_breaklines
from .tin import TileShare, delaunay, filter_blunders, flat_points, residual_histogram, spread
from .tin_dem import (
    EDGE_SPACINGS,
    SPACING_SAMPLE,
    DemParams,
    SurfaceSettings,
    output_crs,
    surface_on_grid,
    tin_vertices,
)
from .tin_grid import Grid

#: the margin of a tile in maximum triangle edges
MARGIN_EDGES = 4.0
#: points read at a time
CHUNK = 1_000_000
#: a point in a work file: output CRS coordinates, ellipsoidal height, sigma_h (NaN: none), sampled for the spacing,
#: tier (cell_dem: UNREFINED a dense point LSM left unrefined, its rho NaN; TWO_RAYS a point of two rays; else
#: THREE_RAYS)
POINT = np.dtype([("x", "f8"), ("y", "f8"), ("z", "f8"), ("sigma", "f8"), ("sample", "?"), ("tier", "u1")])


@dataclass
class TiledDem:
    """What dem_from_point_cloud wrote."""

    path: str
    grid: Grid
    srs: object
    datum: str
    tiles: int
    points: int = 0  # in the TINs of the tiles' own cells (breakline vertices included)
    removed: list = field(default_factory=list)  # blunders per filter iteration, summed over tiles
    dropped_near_breaklines: int = 0
    breakline_vertices: int = 0
    defined: float = 0.0  # fraction of the cells with a height
    max_edge: float = 0.0
    precision_path: str = None
    count_path: str = None
    method: str = "tin"
    filled: int = 0  # gap cells filled (method "cells" with DemParams.fill)
    mask_path: str = None  # the mask raster (method "cells": own points, neighbours', filled, gap)
    own: float = 0.0  # method "cells": fraction of the cells with points of their own

    def summary(self):
        if self.method == "cells":
            fill = (
                f"; {self.filled} gap cells filled ({self.filled / (self.grid.rows * self.grid.cols):.1%}), "
                f"flagged in {self.mask_path}"
                if self.mask_path
                else ""
            )
            return (
                f"{self.points} points in per-cell medians ({sum(self.removed)} outliers removed), "
                f"{self.grid.cols} x {self.grid.rows} cells of {self.grid.cell:g} in {self.tiles} tile(s), "
                f"{self.defined:.1%} measured ({self.own:.1%} from points of their own, the others from "
                f"the cells around), {self.datum} heights{fill}"
            )
        return (
            f"{self.points} points ({sum(self.removed)} blunders removed: {self.removed} per iteration; "
            f"{self.dropped_near_breaklines} next to breaklines dropped; {self.breakline_vertices} breakline "
            f"vertices), {self.grid.cols} x {self.grid.rows} cells of {self.grid.cell:g} in {self.tiles} "
            f"tile(s), {self.defined:.1%} defined, maximum edge {self.max_edge:.4g}, {self.datum} heights"
        )


def _centre(path, crs, feedback):
    """(count, mean x, mean y, srs, whether the points have sigma_h) of the finite points of the cloud, in
    its own CRS."""
    count, sx, sy, srs, sigma = 0, 0.0, 0.0, None, False
    for points in point_chunks(path, crs, CHUNK):
        progress.step(feedback, 0)  # the cancel button
        srs = points.srs
        sigma = sigma or (points.sigma_h is not None and bool(np.isfinite(points.sigma_h).any()))
        finite = np.isfinite(points.x) & np.isfinite(points.y) & np.isfinite(points.z)
        count += int(finite.sum())
        sx += float(points.x[finite].sum())
        sy += float(points.y[finite].sum())
    if count < 3:
        raise InputError(
            f"a DEM needs at least 3 points with finite coordinates, the point cloud has {count}: "
            "check the input point cloud"
        )
    return count, sx / count, sy / count, srs, sigma


def _tiers(fields, finite):
    """cell_dem's tier of the `finite` points of a chunk from its cloud fields rho and rays (module docstring);
    THREE_RAYS where the cloud has neither."""
    n = int(finite.sum())
    rays = np.asarray(fields["rays"])[finite] if fields.get("rays") is not None else np.full(n, 3)
    rho = np.asarray(fields["rho"], float)[finite] if fields.get("rho") is not None else np.zeros(n)
    return point_tiers(rho, rays)


def _to_work_chunks(path, crs, target, count, work, feedback):
    """Write the finite points of the cloud in the output CRS `target` as work chunks (POINT); returns
    (chunk files, bounds (xmin, ymin, xmax, ymax))."""
    sample = np.linspace(0, count - 1, min(count, SPACING_SAMPLE)).astype(np.int64)
    files, seen, lo, hi = [], 0, np.full(2, np.inf), np.full(2, -np.inf)
    for k, points in enumerate(point_chunks(path, crs, CHUNK)):
        if feedback is not None and feedback.isCanceled():
            raise CancelledError("cancelled by the user")
        finite = np.isfinite(points.x) & np.isfinite(points.y) & np.isfinite(points.z)
        pts = points.to(target)
        lost = finite & ~(np.isfinite(pts.x) & np.isfinite(pts.y))
        if lost.any():
            raise InputError(
                f"{int(lost.sum())} points cannot be expressed in the output CRS {target.GetName()} "
                "(outside the area its projection covers): choose an output CRS for where the point "
                "cloud lies, or leave it empty for the points' UTM zone"
            )
        rows = np.zeros(int(finite.sum()), POINT)
        rows["x"], rows["y"], rows["z"] = pts.x[finite], pts.y[finite], pts.z[finite]
        rows["sigma"] = pts.sigma_h[finite] if pts.sigma_h is not None else np.nan
        rows["sample"] = np.isin(np.arange(seen, seen + len(rows)), sample)
        rows["tier"] = _tiers(pts.fields, finite)
        seen += len(rows)
        if len(rows):
            lo = np.minimum(lo, [rows["x"].min(), rows["y"].min()])
            hi = np.maximum(hi, [rows["x"].max(), rows["y"].max()])
        files.append(save_array(os.path.join(work, f"chunk-{k:05d}.npy"), rows, "the DEM's work files"))
        progress.step(feedback, 100.0 * seen / count)
    return files, (lo[0], lo[1], hi[0], hi[1])


def _bucket(chunks, grid, tile, margin, work, name, feedback):
    """Append each point of the work chunks to the file of every `tile` x `tile` cell tile (tiling.tile_grid)
    whose box widened by `margin` (CRS units) holds it; returns the files (None for a tile without points)."""
    across, down = math.ceil(grid.cols / tile), math.ceil(grid.rows / tile)
    reach = margin / grid.cell / tile  # the margin in tiles
    span = int(math.ceil(2 * reach)) + 1  # tiles a widened point can touch per axis
    files = [None] * (across * down)
    for k, chunk in enumerate(chunks):
        progress.step(feedback, 100.0 * k / len(chunks))
        rows = np.load(chunk)
        u, v = (rows["x"] - grid.x0) / grid.cell / tile, (grid.y0 - rows["y"]) / grid.cell / tile
        first_u, last_u = np.floor(u - reach).astype(np.int64), np.floor(u + reach).astype(np.int64)
        first_v, last_v = np.floor(v - reach).astype(np.int64), np.floor(v + reach).astype(np.int64)
        for a in range(span):
            for b in range(span):
                tu, tv = first_u + a, first_v + b
                ok = (tu <= last_u) & (tv <= last_v) & (tu >= 0) & (tv >= 0) & (tu < across) & (tv < down)
                index = (tv * across + tu)[ok]
                order = np.argsort(index, kind="stable")
                tiles, starts = np.unique(index[order], return_index=True)
                selected = rows[ok][order]
                for t, lo, hi in zip(tiles, starts, np.append(starts[1:], len(order))):
                    if files[t] is None:
                        files[t] = os.path.join(work, f"{name}-{t:05d}.bin")
                    append_bytes(files[t], selected[lo:hi].tobytes(), "the DEM's work files")
    return files


def _owner(grid, box):
    """own(x, y): whether points lie in the tile `box` (cells) by their cell, the grid's last row and column
    holding the points on its far edge: every point of the grid has one owner tile."""
    c0, r0, c1, r1 = box

    def own(x, y):
        col = np.clip(np.floor((np.asarray(x) - grid.x0) / grid.cell), 0, grid.cols - 1)
        row = np.clip(np.floor((grid.y0 - np.asarray(y)) / grid.cell), 0, grid.rows - 1)
        return (col >= c0) & (col < c1) & (row >= r0) & (row < r1)

    return own


def _tile_grid(grid, box):
    c0, r0, c1, r1 = box
    return Grid(grid.x0 + c0 * grid.cell, grid.y0 - r0 * grid.cell, grid.cell, c1 - c0, r1 - r0)


def _spacings(grid, box, points_file):
    """Task: nearest-neighbour distances of the sampled points in the tile's own cells."""
    rows = np.fromfile(points_file, POINT)
    inside = rows["sample"] & _owner(grid, box)(rows["x"], rows["y"])
    if not inside.any() or len(rows) < 2:
        return np.zeros(0)
    xy = np.column_stack([rows["x"], rows["y"]])
    return cKDTree(xy).query(xy[inside], k=2)[0][:, 1]


def _residual_tile(job, box, points_file, spreads):
    """Task: the residual histogram (tin.residual_histogram) of the points the tile `box` owns, after the
    blunder filter's iterations with the given `spreads`."""
    grid, _, _, max_edge, k, _, breaklines, margin, _ = job
    rows = np.fromfile(points_file, POINT)
    sub = _tile_grid(grid, box)
    x, y, z, _, fixed, inside, _ = tin_vertices(
        rows["x"], rows["y"], rows["z"], None, grid.cell, max_edge, _near(breaklines, sub, margin), _owner(grid, box)
    )
    if len(x) < 3 or flat_points(x, y):
        return histogram.EMPTY
    tin = delaunay(x, y)
    check_cancel()  # between the stages (execution: a cancel reaches a running tile)
    keep, _ = filter_blunders(tin, x, y, z, k=k, fixed=fixed, tile=TileShare(spreads))
    return residual_histogram(tin, x, y, z, keep, fixed, inside)


def _spreads(job, used, execution, feedback):
    """The blunder filter's (centre, sigma) per iteration from the residuals of all tiles (module docstring,
    4.): one round of tasks per iteration, until no point lies beyond k sigmas."""
    k, iterations = job[4], job[5]
    spreads = []
    if k <= 0:
        return spreads
    for i in range(iterations):
        hists = run_tasks(
            _residual_tile,
            [(job, box, f, list(spreads)) for box, f, _ in used],
            execution,
            progress.scaled(feedback, 100.0 * i / iterations, 100.0 * (i + 1) / iterations),
            f"the blunder filter's iteration {i + 1}",
        )
        given = spread(histogram.total(hists), k)
        if given is None or given[2] == 0:
            break
        spreads.append(given[:2])
    return spreads


def _dem_tile(job, box, points_file, spreads, out, precision_out):
    """Task: the tile `box` (cells) of the DEM from the points of `points_file` with the blunder filter's
    `spreads`, written to `out` (and the precision raster to `precision_out`); returns its counts."""
    grid, wkt, datum, max_edge, k, iterations, breaklines, margin, sigma = job
    srs = parse_crs(wkt)
    rows = np.fromfile(points_file, POINT)
    sub = _tile_grid(grid, box)
    result = surface_on_grid(
        PointSet(rows["x"], rows["y"], rows["z"], srs, {"sigma_h": rows["sigma"]} if sigma else {}),
        sub,
        SurfaceSettings(max_edge, datum, k, iterations, precision_out is not None),
        breaklines=_near(breaklines, sub, margin),
        own=_owner(grid, box),
        spreads=spreads,
    )
    check_cancel()  # before the writes (execution: a cancel reaches a running tile)
    write_float_raster(out, result.heights, sub.geotransform, srs, overviews=False)
    if precision_out is not None:
        write_float_raster(precision_out, result.precision, sub.geotransform, srs, overviews=False)
    flat = flat_points(rows["x"], rows["y"]) if len(rows) >= 3 else "are fewer than 3"
    return {
        "flat": flat,
        "points": result.points,
        "removed": result.removed,
        "dropped": result.dropped_near_breaklines,
        "vertices": result.breakline_vertices,
        "defined": int(np.isfinite(result.heights).sum()),
        "precision_kind": result.precision_kind,
    }


def _cell_tile(job, box, points_file, out, precision_out, count_out, ring_out):
    """Task (method "cells"): the tile `box` (cells) of the DEM from the points of `points_file`, written to
    `out` (and the precision, count and ring rasters where asked); returns its counts."""
    grid, wkt, k, sigma, fallback, radius = job
    srs = parse_crs(wkt)
    rows = np.fromfile(points_file, POINT)
    sub = _tile_grid(grid, box)
    cells = cells_on_grid(
        rows["x"],
        rows["y"],
        rows["z"],
        rows["sigma"] if sigma else None,
        sub,
        CellSettings(k=k, fallback=fallback, radius=radius),
        own=_owner(grid, box),
        tier=rows["tier"],
    )
    check_cancel()  # before the writes (execution: a cancel reaches a running tile)
    write_float_raster(out, cells.heights, sub.geotransform, srs, overviews=False)
    for path, values in ((precision_out, cells.precision), (count_out, cells.counts), (ring_out, cells.ring)):
        if path is not None:
            write_float_raster(path, values, sub.geotransform, srs, overviews=False)
    own = cells.ring == 0
    return {
        "points": int(cells.counts[own].sum()),
        "removed": cells.removed,
        "defined": int(np.isfinite(cells.heights).sum()),
        "own": int(own.sum()),
    }


def _cells_dem(cloud, output, params, precision_path, count_path, mask_path, feedback):
    """The DEM step with method "cells" (module docstring)."""
    count, mx, my, cloud_srs, has_sigma = _centre(cloud, params.input_crs, progress.scaled(feedback, 0, 3))
    target = output_crs(cloud_srs, mx, my, params.crs)
    with work_dir(output, "the DEM tiles") as work:
        chunks, (x0, y0, x1, y1) = _to_work_chunks(
            cloud, params.input_crs, target, count, work, progress.scaled(feedback, 3, 10)
        )
        grid = Grid.covering(np.array([x0, x1]), np.array([y0, y1]), params.cell)
        check_grid_cells(grid.cols, grid.rows, params.cell, target, (x1 - x0, y1 - y0), "the DEM")
        boxes = tile_grid((grid.cols, grid.rows), int(params.tile))
        files = _bucket(
            chunks,
            grid,
            int(params.tile),
            (int(params.radius) + 0.5) * params.cell,
            work,
            "tile",
            progress.scaled(feedback, 10, 20),
        )
        for chunk in chunks:
            os.unlink(chunk)
        job = (grid, target.ExportToWkt(), params.k, has_sigma, params.fallback, int(params.radius))
        used = [(box, f, k) for k, (box, f) in enumerate(zip(boxes, files)) if f is not None]
        names = {
            kind: [os.path.join(work, f"{kind}-{k:05d}.tif") if wanted else None for _, _, k in used]
            for kind, wanted in (
                ("dem", True),
                ("precision", precision_path),
                ("count", count_path),
                ("ring", mask_path),
            )
        }
        with session(params.execution):
            done = run_tasks(
                _cell_tile,
                [
                    (job, box, f, *outs)
                    for (box, f, _), *outs in zip(used, names["dem"], names["precision"], names["count"], names["ring"])
                ],
                params.execution,
                progress.scaled(feedback, 20, 80),
                "the DEM tiles",
            )
        defined = sum(d["defined"] for d in done)
        removed = sum(d["removed"] for d in done)
        own = sum(d["own"] for d in done)
        result = TiledDem(
            output,
            grid,
            target,
            params.datum,
            len(boxes),
            points=sum(d["points"] for d in done),
            removed=[removed],
            defined=defined / (grid.rows * grid.cols),
            precision_path=precision_path or None,
            count_path=count_path or None,
            method="cells",
            mask_path=mask_path or None,
            own=own / (grid.rows * grid.cols),
        )
        datum = "WGS 84 ellipsoidal height" if params.datum == "ellipsoidal" else "EGM96 height (h - N)"
        extra = [
            (path, names[kind], description)
            for kind, path, description in (
                ("precision", precision_path, "standard error of the cell's height (m)"),
                ("count", count_path, "points in the cell"),
            )
        ]
        paths = [output, *(path for path, _, _ in extra), mask_path or None]
        with raster_outputs(paths, params.cog) as (tmp, *temps, mask_tmp):  # every output renamed at the end, or none
            assemble_tiles(
                names["dem"],
                tmp,
                Frame(grid.geotransform, (grid.cols, grid.rows), target),
                description=f"height ({datum}, m)",
                metadata={
                    "HEIGHT_DATUM": datum,
                    "POINTS": result.points,
                    "OUTLIERS_REMOVED": removed,
                    "METHOD": "per-cell median",
                    "RADIUS_CELLS": int(params.radius),
                    "GAPS_FILLED_WITHIN_CELLS": params.fill,
                },
                overviews=None if mask_path else "AVERAGE",
                feedback=progress.scaled(feedback, 80, 90),
            )
            if mask_tmp:
                rings = os.path.join(work, "rings.tif")
                assemble_tiles(
                    names["ring"], rings, Frame(grid.geotransform, (grid.cols, grid.rows), target), overviews=None
                )
                result.filled = fill_gaps(
                    tmp,
                    mask_tmp,
                    params.fill,
                    progress.scaled(feedback, 90, 94),
                    rings=rings,
                )
            for (path, tiles, description), tmp_extra in zip(extra, temps):
                if path:
                    assemble_tiles(
                        tiles,
                        tmp_extra,
                        Frame(grid.geotransform, (grid.cols, grid.rows), target),
                        description=description,
                        feedback=progress.scaled(feedback, 94, 100),
                    )
    if result.points == 0:
        raise InputError("no point of the point cloud lies in a cell of the grid: check the point cloud")
    return result


def mask_output(output, params, mask_path=None):
    """Where the per-cell DEM `output` with DemParams `params` writes its cell mask: `mask_path` where given, else
    beside it ('<stem>_filled.tif') where it fills gaps; None where it writes none."""
    if mask_path or not params.fill:
        return mask_path or None
    return os.path.splitext(os.fspath(output))[0] + "_filled.tif"


def dem_from_point_cloud(
    cloud, output, params=None, breaklines=None, precision_path=None, feedback=None, count_path=None, mask_path=None
):
    """The DEM step: the point cloud file `cloud` (point_input.point_chunks) interpolated with DemParams
    `params` tile by tile (module docstring) and written to the GeoTIFF `output` (and the precision raster
    to `precision_path`, with method "cells" the count of points per cell to `count_path`, where given, and
    with DemParams.fill the mask of the filled cells to `mask_path`, by default beside the output).
    `breaklines`: (path, layer name or None) of a 3-D line layer, or None (method "tin"). Returns a TiledDem;
    raises InputError (unreadable input, no CRS, too few points, breaklines or a count raster with the
    wrong method), ExecutionError, CancelledError."""
    params = (params or DemParams()).check()
    log = progress.ensure(feedback)
    if params.method == "cells":
        if breaklines:
            raise InputError(
                "breaklines shape a TIN: the per-cell DEM does not use them; choose the TIN method or "
                "leave the breaklines out"
            )
        result = _cells_dem(
            cloud, output, params, precision_path, count_path, mask_output(output, params, mask_path), feedback
        )
        log.pushInfo(result.summary())
        return result
    if count_path:
        raise InputError("the count of points per cell is an output of the per-cell method, not of the TIN")
    if params.fill:
        raise InputError(
            "gap filling is for the per-cell DEM: the TIN interpolates between its points already, and "
            "leaves gaps only under triangles longer than the maximum edge (raise it to fill more)"
        )
    lines, lines_srs = read_breaklines(*breaklines) if breaklines else ([], None)
    count, mx, my, cloud_srs, has_sigma = _centre(cloud, params.input_crs, progress.scaled(feedback, 0, 3))
    target = output_crs(cloud_srs, mx, my, params.crs)
    lines = [np.column_stack([transform(lines_srs, target, b[:, :2], "the breaklines")[:, :2], b[:, 2]]) for b in lines]
    with work_dir(output, "the DEM tiles") as work:
        chunks, (x0, y0, x1, y1) = _to_work_chunks(
            cloud, params.input_crs, target, count, work, progress.scaled(feedback, 3, 8)
        )
        grid = Grid.covering(np.array([x0, x1]), np.array([y0, y1]), params.cell)
        if min(x1 - x0, y1 - y0) > 0:  # else the TIN names the points at one position (tin.flat_points)
            check_grid_cells(grid.cols, grid.rows, params.cell, target, (x1 - x0, y1 - y0), "the DEM")
        tile = int(params.tile)
        boxes = tile_grid((grid.cols, grid.rows), tile)
        spacing = math.sqrt(max((x1 - x0) * (y1 - y0), params.cell**2) / count)  # >= the median NN distance
        edge = params.max_edge if params.max_edge is not None else max(3 * params.cell, EDGE_SPACINGS * spacing)
        margin = MARGIN_EDGES * edge
        files = _bucket(chunks, grid, tile, margin, work, "tile", progress.scaled(feedback, 8, 10))
        with session(params.execution):  # the rounds of tasks share the workers
            max_edge = params.max_edge
            if max_edge is None:
                tasks = [(grid, box, f) for box, f in zip(boxes, files) if f is not None]
                distances = np.concatenate(
                    run_tasks(
                        _spacings, tasks, params.execution, progress.scaled(feedback, 10, 20), "the point spacing"
                    )
                    + [np.zeros(0)]
                )
                median = float(np.median(distances)) if len(distances) else 0.0
                max_edge = max(3.0 * params.cell, EDGE_SPACINGS * median)
                if max_edge > edge:
                    margin = MARGIN_EDGES * max_edge
                    log.pushInfo(
                        f"the maximum edge {max_edge:.4g} exceeds the density's bound {edge:.4g}: the tiles' "
                        f"margin is widened to {margin:.4g}"
                    )
                    for f in files:
                        if f is not None:
                            os.unlink(f)
                    files = _bucket(chunks, grid, tile, margin, work, "wide", progress.scaled(feedback, 20, 22))
            for chunk in chunks:
                os.unlink(chunk)
            job = (
                grid,
                target.ExportToWkt(),
                params.datum,
                max_edge,
                params.k,
                params.iterations,
                _near(lines, grid, margin),
                margin,
                has_sigma,
            )
            used = [(box, f, k) for k, (box, f) in enumerate(zip(boxes, files)) if f is not None]
            outs = [os.path.join(work, f"dem-{k:05d}.tif") for _, _, k in used]
            precisions = [os.path.join(work, f"precision-{k:05d}.tif") if precision_path else None for _, _, k in used]
            spreads = _spreads(job, used, params.execution, progress.scaled(feedback, 20, 50))
            done = run_tasks(
                _dem_tile,
                [(job, box, f, spreads, out, p) for (box, f, _), out, p in zip(used, outs, precisions)],
                params.execution,
                progress.scaled(feedback, 50, 80),
                "the DEM tiles",
            )
        defined = sum(d["defined"] for d in done)
        if all(d["flat"] for d in done):
            where = f" {done[0]['flat']}" if len(done) == 1 else ", in every tile, span no area:"
            raise InputError(
                f"the {count} points of the point cloud{where}: a TIN needs at least 3 points that "
                "are not on one line; check the point cloud (duplicated points, or coordinates lost or "
                "rounded in an export?)"
            )
        if defined == 0:
            raise InputError(
                f"no grid cell lies in a triangle with edges up to {max_edge:g}: raise the maximum edge "
                f"length or the cell size ({params.cell:g})"
            )
        removed = [
            sum(d["removed"][i] for d in done if len(d["removed"]) > i)
            for i in range(max((len(d["removed"]) for d in done), default=0))
        ]
        result = TiledDem(
            output,
            grid,
            target,
            params.datum,
            len(boxes),
            points=sum(d["points"] for d in done),
            removed=removed,
            dropped_near_breaklines=sum(d["dropped"] for d in done),
            breakline_vertices=sum(d["vertices"] for d in done),
            defined=defined / (grid.rows * grid.cols),
            max_edge=max_edge,
            precision_path=precision_path or None,
        )
        datum = "WGS 84 ellipsoidal height" if params.datum == "ellipsoidal" else "EGM96 height (h - N)"
        # both outputs are renamed at the end, or neither
        with raster_outputs([output, precision_path or None], params.cog) as (tmp, tmp_precision):
            assemble_tiles(
                outs,
                tmp,
                Frame(grid.geotransform, (grid.cols, grid.rows), target),
                description=f"height ({datum}, m)",
                metadata={"HEIGHT_DATUM": datum, "POINTS": result.points, "BLUNDERS_REMOVED": sum(removed)},
                feedback=progress.scaled(feedback, 80, 95 if precision_path else 100),
            )
            if precision_path:
                assemble_tiles(
                    precisions,
                    tmp_precision,
                    Frame(grid.geotransform, (grid.cols, grid.rows), target),
                    description=done[0]["precision_kind"],
                    feedback=progress.scaled(feedback, 95, 100),
                )
    log.pushInfo(result.summary())
    return result


def _near(lines, grid, margin):
    """The breaklines whose bounding box comes within `margin` of the grid (the others do not reach it)."""
    x0, y1 = grid.x0 - margin, grid.y0 + margin
    x1, y0 = grid.x0 + grid.cols * grid.cell + margin, grid.y0 - grid.rows * grid.cell - margin
    return [
        b for b in lines if b[:, 0].max() >= x0 and b[:, 0].min() <= x1 and b[:, 1].max() >= y0 and b[:, 1].min() <= y1
    ]
