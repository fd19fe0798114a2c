"""DEM from a point cloud (Kornus et al. 2006, section 3.6): Delaunay TIN of the object points (breaklines as
conforming constraints), blunder filter against the TIN neighbours, linear interpolation on a regular
grid in the output CRS, gaps where triangles are longer than a threshold (no surface invented over
unmatched water or forest), heights ellipsoidal or EGM96 (PROJ), an optional precision raster.

The precision raster is the points' a priori sigma_h interpolated on the same TIN where the cloud has
it (pushbroom:intersectpoints writes it; a breakline vertex takes that of the nearest point),
otherwise the distance (CRS units) from each cell centre to the nearest point of the TIN."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from .. import progress
from ..crs import egm96_undulation, reproject, transform, wgs84
from ..errors import InputError
from ..execution import Execution
from ..progress import Feedback
from .geotiff import write_float_raster
from .point_input import PointSet
from .pointcloud import output_srs
from .tin import TileShare, conform_breaklines, delaunay, filter_blunders, flat_points, longest_edge
from .tin_grid import Grid, rasterize

DATUMS = ("ellipsoidal", "egm96")
#: interpolation methods of the DEM step: a TIN of the points (sparse points), or per-cell medians (dense
#: points, cell_dem.py)
METHODS = ("tin", "cells")
#: cells: the largest radius of the per-cell method (each point is offered to (2 r + 1)^2 cells)
MAX_RADIUS = 5


@dataclass
class DemResult:
    """heights and precision (rows, cols; NaN = gap) on `grid` in `srs`, and what was done."""

    heights: np.ndarray
    grid: Grid
    srs: object
    datum: str
    precision: np.ndarray = None
    precision_kind: str = ""
    points: int = 0
    removed: list = field(default_factory=list)
    dropped_near_breaklines: int = 0
    breakline_vertices: int = 0

    def summary(self):
        defined = np.isfinite(self.heights)
        return (
            f"{self.points} points ({sum(self.removed)} blunders removed: {self.removed} per iteration; "
            f"{self.dropped_near_breaklines} next to breaklines dropped; {self.breakline_vertices} "
            f"breakline vertices), {self.grid.cols} x {self.grid.rows} cells of {self.grid.cell:g}, "
            f"{defined.mean():.1%} defined, {self.datum} heights"
        )


#: default maximum triangle edge in point spacings: bridges one missing point of a matching lattice
#: (edges 2 to 2.24 spacings), not two
EDGE_SPACINGS = 2.5
#: points sampled for the point spacing
SPACING_SAMPLE = 10_000


def default_max_edge(x, y, cell):
    """max(3 cells, EDGE_SPACINGS x the median nearest-neighbour distance of the points): gaps where
    a triangle spans more than one missing point, never finer than the grid can show."""
    tree = cKDTree(np.column_stack([x, y]))
    sample = np.linspace(0, len(x) - 1, min(len(x), SPACING_SAMPLE)).astype(int)
    spacing = float(np.median(tree.query(np.column_stack([x[sample], y[sample]]), k=2)[0][:, 1]))
    return max(3.0 * cell, EDGE_SPACINGS * spacing)


def output_crs(srs, x, y, crs=None):
    """The DEM's CRS (osr.SpatialReference) for points centred at (x, y) in `srs`: `crs` (InputError where
    its area of use is far from the points), or the UTM zone of the centre where `crs` is None or ''."""
    ll = transform(srs, wgs84(), np.array([[x, y]], float), "the point cloud's centre")
    return output_srs(crs, ll[:, 0], ll[:, 1], "the point cloud")


@dataclass(frozen=True)
class SurfaceSettings:
    """How surface_on_grid makes a TIN surface: triangles with an edge longer than `max_edge` are gaps;
    the blunder filter removes points beyond `k` robust sigmas (0: no filter) in `iterations`; `datum`
    'ellipsoidal' or 'egm96' (H = h - N); `precision`: the precision raster too."""

    max_edge: float
    datum: str = "ellipsoidal"
    k: float = 4.0
    iterations: int = 3
    precision: bool = False


def interpolate_dem(
    points: PointSet,
    params: DemParams | None = None,
    breaklines: Sequence[np.ndarray] = (),
    breakline_srs: Any = None,
    precision: bool = False,
    feedback: Feedback | None = None,
) -> DemResult:
    """DemResult of a PointSet (point_input.py; z ellipsoidal) with the DemParams `params` (default: its
    defaults) of a TIN: its `cell`; `crs` the output CRS (default: the UTM zone of the points); `max_edge`:
    triangles with a longer edge are gaps (default `default_max_edge`); `k`: blunder threshold in robust
    sigmas (0: no filter), `iterations` of the filter; `datum`: 'ellipsoidal' or 'egm96' (H = h - N).
    `breaklines`: (n, 3) arrays (x, y in `breakline_srs`, an osr.SpatialReference, default the output CRS;
    z as the points'); `precision`: the precision raster too."""
    params = params or DemParams()
    cell, datum, max_edge = params.cell, params.datum, params.max_edge
    if datum not in DATUMS:
        raise InputError(f"the height datum must be one of {', '.join(DATUMS)}, not {datum!r}")
    finite = np.isfinite(points.x) & np.isfinite(points.y) & np.isfinite(points.z)
    if len(points) < 3 or finite.sum() < 3:
        raise InputError(
            f"a DEM needs at least 3 points with finite coordinates, the point cloud has "
            f"{int(finite.sum())}: check the input point cloud"
        )
    progress.step(feedback, 0, f"{len(points)} points ({len(points) - int(finite.sum())} not finite, left out)")
    target = output_crs(points.srs, np.mean(points.x[finite]), np.mean(points.y[finite]), params.crs)
    pts = points.to(target)
    lost = finite & ~(np.isfinite(pts.x) & np.isfinite(pts.y))
    if lost.any():
        raise InputError(
            f"{int(lost.sum())} of the {len(points)} points cannot be expressed in the output CRS "
            f"{target.GetName()} (outside the area its projection covers): choose an output CRS for "
            "where the point cloud lies, or leave it empty for the points' UTM zone"
        )
    x, y, z = pts.x[finite], pts.y[finite], pts.z[finite]
    sigma = pts.sigma_h[finite] if pts.sigma_h is not None else None
    max_edge = default_max_edge(x, y, cell) if max_edge is None else float(max_edge)
    grid = Grid.covering(x, y, cell)
    if breakline_srs is not None:
        breaklines = [
            np.column_stack([transform(breakline_srs, target, b[:, :2], "the breaklines")[:, :2], b[:, 2]])
            for b in breaklines
        ]
    if len(x) >= 3 and flat_points(x, y):
        delaunay(x, y)  # the clear InputError of points that span no area
    result = surface_on_grid(
        PointSet(x, y, z, target, {} if sigma is None else {"sigma_h": sigma}),
        grid,
        SurfaceSettings(max_edge, datum, params.k, params.iterations, precision),
        breaklines=breaklines,
        feedback=feedback,
    )
    if not np.isfinite(result.heights).any():
        raise InputError(
            f"no grid cell lies in a triangle with edges up to {max_edge:g}: raise the maximum edge "
            f"length or the cell size ({cell:g})"
        )
    progress.step(feedback, 100, result.summary())
    return result


def tin_vertices(x, y, z, sigma, cell, max_edge, breaklines=(), own=None):
    """The TIN's vertices: the points x, y, z with their sigma_h (or None) and the breakline vertices
    (conform_breaklines, spacing min(cell, max_edge) / 2; (n, 3) arrays in the points' CRS) added, the points
    too close to a breakline dropped. Returns (x, y, z, sigma, fixed: breakline vertex, inside: where
    `own(x, y)` is True (default all), points dropped where `own` holds them)."""
    own = own or (lambda px, py: np.ones(len(px), bool))
    inside = own(x, y)
    vertices, _, near = conform_breaklines(
        list(breaklines), x, y, spacing=min(cell, max_edge) / 2, min_length=cell / 20
    )
    dropped = int((inside & ~near).sum())
    x, y, z = (np.concatenate([v[near], vertices[:, i]]) for i, v in enumerate((x, y, z)))
    fixed = np.arange(len(x)) >= int(near.sum())
    inside = np.concatenate([inside[near], own(vertices[:, 0], vertices[:, 1])])
    if sigma is not None:  # a breakline vertex takes the sigma_h of the nearest point
        sigma = sigma[near]
        nearest = cKDTree(np.column_stack([x[: len(sigma)], y[: len(sigma)]])).query(vertices[:, :2])[1]
        sigma = np.concatenate([sigma, sigma[nearest]])
    return x, y, z, sigma, fixed, inside, dropped


def surface_on_grid(
    points: PointSet,
    grid: Grid,
    settings: SurfaceSettings,
    breaklines: Sequence[np.ndarray] = (),
    own: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    spreads: Sequence[tuple[float, float]] | None = None,
    feedback: Feedback | None = None,
) -> DemResult:
    """The DemResult of `points` (x, y in their srs, the grid's CRS; z ellipsoidal; their sigma_h where
    they have it) on `grid` with SurfaceSettings `settings`: breakline vertices added (tin_vertices),
    Delaunay TIN, blunder filter (`k` robust sigmas, `iterations`; with `spreads`, those given per
    iteration: tin.filter_blunders), linear interpolation in the triangles with edges up to `max_edge`,
    the precision raster where asked, EGM96 heights for that `datum`. Cells outside every used triangle
    are NaN: all of them where the points span no area (tin.flat_points). The counts (points and vertices
    left in the TIN, blunders removed, points dropped) are of the points and vertices where `own(x, y)` is
    True (default: all), so that a tile's counts leave out its margin."""
    srs, max_edge, datum, k, precision = points.srs, settings.max_edge, settings.datum, settings.k, settings.precision
    cell = grid.cell
    x, y, z, sigma, fixed, inside, dropped = tin_vertices(
        points.x, points.y, points.z, points.sigma_h, cell, max_edge, breaklines, own
    )
    result = DemResult(
        np.full(grid.shape, np.nan),
        grid,
        srs,
        datum,
        points=int(inside.sum()),
        dropped_near_breaklines=dropped,
        breakline_vertices=int((fixed & inside).sum()),
    )
    if precision:
        result.precision = np.full(grid.shape, np.nan)
        result.precision_kind = (
            "interpolated point sigma_h (m)" if sigma is not None else "distance to the nearest point (CRS units)"
        )
    if len(x) < 3 or flat_points(x, y):
        return result
    progress.step(feedback, 10, "Delaunay triangulation")
    tin = delaunay(x, y)
    if k > 0:
        keep, result.removed = filter_blunders(
            tin, x, y, z, k=k, iterations=settings.iterations, fixed=fixed, tile=TileShare(spreads, inside)
        )
        progress.step(
            feedback,
            40,
            f"blunder filter (k = {k:g} robust sigmas): {sum(result.removed)} points removed "
            f"({result.removed} per iteration)",
        )
        result.points -= sum(result.removed)
        if not keep.all():
            x, y, z, fixed = x[keep], y[keep], z[keep], fixed[keep]
            sigma = sigma[keep] if sigma is not None else None
            if len(x) < 3 or flat_points(x, y):
                return result
            tin = delaunay(x, y)
    progress.step(feedback, 60, "interpolating on the grid")
    triangles = tin.simplices
    use = longest_edge(x, y, triangles) <= max_edge
    values = z if sigma is None or not precision else np.column_stack([z, sigma])
    bands = rasterize(x, y, values, triangles, grid, use)
    result.heights = heights = bands if values.ndim == 1 else bands[0]
    defined = np.isfinite(heights)
    if precision:
        progress.step(feedback, 75, "precision raster")
        if values.ndim == 2:
            result.precision = bands[1]
        elif defined.any():
            cx, cy = grid.centres()
            result.precision[defined] = cKDTree(np.column_stack([x, y])).query(
                np.column_stack([cx[defined], cy[defined]]), workers=-1
            )[0]
    if datum == "egm96" and defined.any():
        progress.step(feedback, 85, "EGM96 heights")
        cx, cy = grid.centres()
        heights[defined] -= egm96_undulation(*reproject(cx[defined], cy[defined], srs, wgs84(), "the DEM cells"))
    return result


def write_dem(result, path, precision_path=None, feedback=None):
    """Write the heights (and the precision raster where given a path) as tiled GeoTIFFs."""
    datum = "WGS 84 ellipsoidal height" if result.datum == "ellipsoidal" else "EGM96 height (h - N)"
    metadata = {"HEIGHT_DATUM": datum, "POINTS": result.points, "BLUNDERS_REMOVED": sum(result.removed)}
    write_float_raster(
        path,
        result.heights,
        result.grid.geotransform,
        result.srs,
        f"height ({datum}, m)",
        metadata,
        feedback=progress.scaled(feedback, 0, 80 if precision_path else 100),
    )
    if precision_path:
        if result.precision is None:
            raise InputError("this DEM was interpolated without a precision raster (precision=True)")
        write_float_raster(
            precision_path,
            result.precision,
            result.grid.geotransform,
            result.srs,
            result.precision_kind,
            feedback=progress.scaled(feedback, 80, 100),
        )


@dataclass
class DemParams:
    """The DEM step's settings (pushbroom:interpolatedem); see interpolate_dem."""

    cell: float = 10.0  # output CRS units
    crs: str | None = None  # output CRS (authority id or WKT); None: the UTM zone of the points
    input_crs: str | None = None  # the point cloud's CRS; None: the file's own
    datum: str = "ellipsoidal"  # one of DATUMS
    max_edge: float | None = None  # longer triangles are gaps; None: default_max_edge
    k: float = 4.0  # blunder threshold in robust sigmas (0: no filter)
    iterations: int = 3  # of the blunder filter
    tile: int = 1024  # cells per tile side (dem_tiles.py)
    method: str = "tin"  # one of METHODS
    fallback: bool = True  # "cells": the unrefined dense points where a cell has no refined one
    fill: float = 0.0  # gaps filled from the cells within this many cells (gap_fill.py; 0: none)
    radius: int = 1  # "cells": an empty cell takes the points within this many cells (cell_dem.py)
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # where the tiles run
    cog: bool = False  # the rasters as Cloud-Optimised GeoTIFFs

    def check(self):
        """Raise InputError for settings no interpolation can use."""
        if self.method not in METHODS:
            raise InputError(f"the DEM's method must be one of {', '.join(METHODS)}, got {self.method!r}")
        broken = [
            text
            for ok, text in (
                (0 < self.cell < math.inf, f"the cell size must be a positive number, got {self.cell}"),
                (self.datum in DATUMS, f"the datum must be one of {', '.join(DATUMS)}, got {self.datum!r}"),
                (0 <= self.k < math.inf, f"the blunder threshold must be 0 or more, got {self.k}"),
                (self.iterations >= 1, f"the blunder filter's iterations must be at least 1, got {self.iterations}"),
                (
                    self.max_edge is None or 0 <= self.max_edge <= math.inf,
                    f"the maximum edge must be 0 or more, got {self.max_edge}",
                ),
                (int(self.tile) >= 16, f"the tiles must be at least 16 cells, got {self.tile}"),
                (0 <= self.fill < math.inf, f"the fill distance must be 0 or more cells, got {self.fill}"),
                (0 <= int(self.radius) <= MAX_RADIUS, f"the radius must be 0 to {MAX_RADIUS} cells, got {self.radius}"),
            )
            if not ok
        ]
        if broken:
            raise InputError("; ".join(broken))
        self.execution.check()
        return self
