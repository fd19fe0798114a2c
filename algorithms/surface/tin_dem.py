"""DEM from a point cloud (Kornus et al. 2006, section 3.6): Delaunay TIN of the object points (breaklines as
conforming constraints), blunder filter against the TIN neighbours, linear interpolation on a regular
grid in the output CRS, gaps where triangles are longer than a threshold (no surface invented over
unmatched water or forest), heights ellipsoidal or EGM96 (PROJ), an optional precision raster.

The precision raster is the points' a priori sigma_h interpolated on the same TIN where the cloud has
it (pushbroom:intersectpoints writes it; a breakline vertex takes that of the nearest point),
otherwise the distance (CRS units) from each cell centre to the nearest point of the TIN."""
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .. import progress
from ..crs import egm96_undulation, reproject, transform, wgs84
from ..errors import InputError
from .geotiff import write_float_raster
from .point_input import area_of_use, read_breaklines, read_points, within_area_of_use
from .pointcloud import output_srs
from .tin import conform_breaklines, delaunay, filter_blunders, longest_edge
from .tin_grid import Grid, rasterize

DATUMS = ("ellipsoidal", "egm96")


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
        return (f"{self.points} points ({sum(self.removed)} blunders removed: {self.removed} per iteration; "
                f"{self.dropped_near_breaklines} next to breaklines dropped; {self.breakline_vertices} "
                f"breakline vertices), {self.grid.cols} x {self.grid.rows} cells of {self.grid.cell:g}, "
                f"{defined.mean():.1%} defined, {self.datum} heights")


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


def interpolate_dem(points, cell=10.0, crs=None, datum="ellipsoidal", max_edge=None, k=4.0, iterations=3,
                    breaklines=(), breakline_srs=None, precision=False, feedback=None):
    """DemResult of a PointSet (point_input.py; z ellipsoidal). `crs`: output CRS (default: the UTM
    zone of the points); `max_edge`: triangles with a longer edge are gaps (default `default_max_edge`);
    `k`: blunder threshold in robust sigmas (0: no filter), `iterations` of the filter; `breaklines`:
    (n, 3) arrays (x, y in `breakline_srs`, default the output CRS; z as the points');
    `datum`: 'ellipsoidal' or 'egm96' (H = h - N)."""
    if datum not in DATUMS:
        raise InputError(f"the height datum must be one of {', '.join(DATUMS)}, not {datum!r}")
    finite = np.isfinite(points.x) & np.isfinite(points.y) & np.isfinite(points.z)
    if len(points) < 3 or finite.sum() < 3:
        raise InputError(f"a DEM needs at least 3 points with finite coordinates, the point cloud has "
                         f"{int(finite.sum())}: check the input point cloud")
    progress.step(feedback, 0, f"{len(points)} points ({len(points) - int(finite.sum())} not finite, left out)")
    ll = transform(points.srs, wgs84(), np.column_stack([np.mean(points.x[finite]), np.mean(points.y[finite])]),
                   "the point cloud's centre")
    if crs is None or crs == "":
        target = output_srs(None, ll[:, 0], ll[:, 1])
    else:
        target = output_srs(crs)
        if not within_area_of_use(target, float(ll[0, 0]), float(ll[0, 1])):
            raise InputError(f"the output CRS {target.GetName()} is used at {area_of_use(target)}, far from the point "
                             f"cloud (longitude {ll[0, 0]:.4f}, latitude {ll[0, 1]:.4f}): choose an output CRS for "
                             "where the points lie, or leave it empty for their UTM zone")
    pts = points.to(target)
    lost = finite & ~(np.isfinite(pts.x) & np.isfinite(pts.y))
    if lost.any():
        raise InputError(f"{int(lost.sum())} of the {len(points)} points cannot be expressed in the output CRS "
                         f"{target.GetName()} (outside the area its projection covers): choose an output CRS for "
                         "where the point cloud lies, or leave it empty for the points' UTM zone")
    x, y, z = pts.x[finite], pts.y[finite], pts.z[finite]
    sigma = pts.sigma_h[finite] if pts.sigma_h is not None else None
    max_edge = default_max_edge(x, y, cell) if max_edge is None else float(max_edge)
    grid = Grid.covering(x, y, cell)
    if breakline_srs is not None:
        breaklines = [np.column_stack([transform(breakline_srs, target, b[:, :2], "the breaklines")[:, :2],
                                       b[:, 2]]) for b in breaklines]
    vertices, _, near = conform_breaklines(list(breaklines), x, y, spacing=min(cell, max_edge) / 2,
                                           min_length=cell / 20)
    x, y, z = (np.concatenate([v[near], vertices[:, i]]) for i, v in enumerate((x, y, z)))
    fixed = np.arange(len(x)) >= int(near.sum())
    if sigma is not None:   # a breakline vertex takes the sigma_h of the nearest point
        sigma = sigma[near]
        nearest = cKDTree(np.column_stack([x[:len(sigma)], y[:len(sigma)]])).query(vertices[:, :2])[1]
        sigma = np.concatenate([sigma, sigma[nearest]])
    progress.step(feedback, 10, "Delaunay triangulation")
    tin = delaunay(x, y)
    removed = []
    if k > 0:
        keep, removed = filter_blunders(tin, x, y, z, k=k, iterations=iterations, fixed=fixed)
        progress.step(feedback, 40, f"blunder filter (k = {k:g} robust sigmas): {sum(removed)} points removed "
                                    f"({removed} per iteration)")
        if not keep.all():
            x, y, z, fixed = x[keep], y[keep], z[keep], fixed[keep]
            sigma = sigma[keep] if sigma is not None else None
            tin = delaunay(x, y)
    progress.step(feedback, 60, "interpolating on the grid")
    triangles = tin.simplices
    use = longest_edge(x, y, triangles) <= max_edge
    values = z if sigma is None or not precision else np.column_stack([z, sigma])
    bands = rasterize(x, y, values, triangles, grid, use)
    heights = bands if values.ndim == 1 else bands[0]
    defined = np.isfinite(heights)
    if not defined.any():
        raise InputError(f"no grid cell lies in a triangle with edges up to {max_edge:g}: raise the maximum edge "
                         f"length or the cell size ({cell:g})")
    result = DemResult(heights, grid, target, datum, points=len(x), removed=removed,
                       dropped_near_breaklines=int((~near).sum()), breakline_vertices=int(fixed.sum()))
    if precision:
        progress.step(feedback, 75, "precision raster")
        if values.ndim == 2:
            result.precision, result.precision_kind = bands[1], "interpolated point sigma_h (m)"
        else:
            cx, cy = grid.centres()
            result.precision = np.full(grid.shape, np.nan)
            result.precision[defined] = cKDTree(np.column_stack([x, y])).query(
                np.column_stack([cx[defined], cy[defined]]), workers=-1)[0]
            result.precision_kind = "distance to the nearest point (CRS units)"
    if datum == "egm96":
        progress.step(feedback, 85, "EGM96 heights")
        cx, cy = grid.centres()
        heights[defined] -= egm96_undulation(*reproject(cx[defined], cy[defined], target, wgs84(), "the DEM cells"))
    progress.step(feedback, 100, result.summary())
    return result


def write_dem(result, path, precision_path=None, feedback=None):
    """Write the heights (and the precision raster where given a path) as tiled GeoTIFFs."""
    datum = "WGS 84 ellipsoidal height" if result.datum == "ellipsoidal" else "EGM96 height (h - N)"
    metadata = {"HEIGHT_DATUM": datum, "POINTS": result.points, "BLUNDERS_REMOVED": sum(result.removed)}
    write_float_raster(path, result.heights, result.grid.geotransform, result.srs, f"height ({datum}, m)",
                       metadata, feedback=progress.scaled(feedback, 0, 80 if precision_path else 100))
    if precision_path:
        if result.precision is None:
            raise InputError("this DEM was interpolated without a precision raster (precision=True)")
        write_float_raster(precision_path, result.precision, result.grid.geotransform, result.srs,
                           result.precision_kind, feedback=progress.scaled(feedback, 80, 100))


@dataclass
class DemParams:
    """The DEM step's settings (pushbroom:interpolatedem); see interpolate_dem."""

    cell: float = 10.0              # output CRS units
    crs: str = None                 # output CRS (authority id or WKT); None: the UTM zone of the points
    input_crs: str = None           # the point cloud's CRS; None: the file's own
    datum: str = "ellipsoidal"      # one of DATUMS
    max_edge: float = None          # longer triangles are gaps; None: default_max_edge
    k: float = 4.0                  # blunder threshold in robust sigmas (0: no filter)
    iterations: int = 3             # of the blunder filter

    def check(self):
        """Raise InputError for settings no interpolation can use."""
        if not self.cell > 0 or self.datum not in DATUMS or self.k < 0 or self.iterations < 1 \
                or (self.max_edge is not None and self.max_edge < 0):
            raise InputError(f"the cell size must be positive, the datum one of {', '.join(DATUMS)}, the blunder "
                             "threshold and the maximum edge not negative and the iterations at least 1")
        return self


def dem_from_point_cloud(cloud, output, params=None, breaklines=None, precision_path=None, feedback=None):
    """The DEM step: the point cloud file `cloud` (point_input.read_points) interpolated with DemParams
    `params` and written to the GeoTIFF `output` (and the precision raster to `precision_path` where
    given). `breaklines`: (path, layer name or None) of a 3-D line layer, or None. Returns the
    DemResult; raises InputError (unreadable input, no CRS, too few points), CancelledError."""
    params = (params or DemParams()).check()
    points = read_points(cloud, params.input_crs)
    lines, lines_srs = read_breaklines(*breaklines) if breaklines else ([], None)
    result = interpolate_dem(points, cell=params.cell, crs=params.crs, datum=params.datum, max_edge=params.max_edge,
                             k=params.k, iterations=params.iterations, breaklines=lines, breakline_srs=lines_srs,
                             precision=bool(precision_path), feedback=progress.scaled(feedback, 0, 85))
    write_dem(result, output, precision_path or None, feedback=progress.scaled(feedback, 85, 100))
    progress.ensure(feedback).pushInfo(result.summary())
    return result
