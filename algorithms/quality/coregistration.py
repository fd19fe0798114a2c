"""Co-registration of a DEM to a reference DEM: the horizontal and vertical shift (and optionally a tilt) that
bring it onto the reference over stable terrain (Nuth and Kääb 2011), found by windows.

Model. A DEM displaced from the reference by a horizontal vector s and a vertical offset b, DEM(x) = ref(x + s) + b,
differs from it over terrain of slope alpha and aspect psi (the downslope azimuth) by Nuth and Kääb's (2011) eq. 3,
dh / tan(alpha) = a cos(b' - psi) + c. Multiplied by tan(alpha), with the aspect's sine and cosine written as the
reference's gradient (dz/de = -tan(alpha) sin(psi), dz/dn = -tan(alpha) cos(psi)), it is linear in the shift:

    dh(x) = DEM'(x) - ref(x) = g_e(x) d_e + g_n(x) d_n + d_z [+ p_e (e - e_c) + p_n (n - n_c)]

where DEM' is the DEM as co-registered so far, g the reference's gradient (m/m, on the DEM's cells), d the
remaining shift (m) and the bracket the optional tilt, a plane about the DEM's centre (e_c, n_c). The residual is
the height difference itself, so flat cells (where dh / tan(alpha) is noise) weigh nothing in the shift and fix the
vertical offset and the tilt. The fit is least squares over the stable cells (below).

Iterations. DEM' is the DEM with its grid moved by the shift t found so far (its geotransform translated: the
heights are never resampled) and the vertical correction added: DEM'(x + t) = DEM(x) - (b + the plane). The reference
is resampled onto DEM''s cells (height_differences.reference_on_grid: the average of its cells inside a cell where
it is finer, bilinear otherwise), dh and the reference's gradient taken there, and the increments fitted; t grows by
the horizontal increment and the vertical correction by the fitted offset and plane. The iterations stop when the
horizontal increment is below `tolerance` cells and the vertical one below TOLERANCE_UP m; a shift still moving after
`max_iterations` is a CoregistrationError naming the last shift, never a result.

Stable terrain. A cell takes part where the DEM and the reference have heights, the reference's slope is at most
`max_slope` degrees (steep slopes: their heights and gradients are the least certain), the unstable mask (a raster,
any CRS; its non-zero cells: forest, water, glaciers, changes) does not cover it, and its dh is within
`outlier_nmad` NMADs of the median dh of the iteration's stable cells (each iteration reads the windows twice: the
median and NMAD first, then the normal equations).

Precision. The shift's covariance is sigma_0^2 N^-1 of the last iteration's fit, sigma_0 the residuals' standard
deviation, times the DEM cells per reference cell where the reference is coarser (its error is one per reference cell,
not one per DEM cell: without the factor a 2 m DSM against 90 m SRTM would claim its shift to centimetres). The
horizontal shift counts as shown where the larger semi-axis of its error ellipse is at most MAX_SIGMA cells of the
coarser DEM; otherwise (slopes facing one way, an area of few reference cells, flat terrain) the fit stops with
ShiftNotShownError, and `horizontal` off fits the vertical offset and the tilt alone.

Memory follows the window: each pass cuts the DEM into WINDOW x WINDOW windows, each a task on the chosen execution
(execution.run_tasks) that returns its normal equations and its dh summary (statistics.DhSummary), which add up.

Failure modes: InputError (inputs that do not overlap, fewer than MIN_CELLS stable cells, a vertical datum the CRS
contradicts), ShiftNotShownError (an InputError: the terrain does not show the horizontal shift),
CoregistrationError (no convergence), CancelledError.

Reference: Nuth, C., Kääb, A., 2011. Co-registration and bias corrections of satellite elevation data sets for
quantifying glacier thickness change. The Cryosphere 5, 271-290."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .. import progress
from ..crs import reproject, srs as parse_crs, undulation_rows
from ..errors import InputError, PushbroomError
from ..execution import Execution, run_tasks
from ..geodesy import metres_per_degree
from ..progress import Feedback
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .height_differences import (
    Reference,
    ReferenceReach,
    check_stated,
    reference_on_grid,
    resampling_onto,
)
from .rasters import Grid, cell_metres, gradient, metres_per_unit, open_raster, raster_srs, read_grid, warp_to
from .statistics import DhSummary

#: cells per side of the windows a pass reads
WINDOW = 1024
#: stable cells the fit needs at least
MIN_CELLS = 100
#: m: the vertical increment below which the iterations have converged (with the horizontal one below `tolerance`)
TOLERANCE_UP = 0.001
#: the largest standard error of the horizontal shift (the larger semi-axis of its error ellipse), in cells of the
#: coarser of the DEM and the reference, at which the terrain still shows the shift (module docstring)
MAX_SIGMA = 0.25


class CoregistrationError(PushbroomError):
    """The co-registration did not converge; its message names the last shift."""


class ShiftNotShownError(InputError):
    """The stable terrain does not show the horizontal shift (flat, one-way slopes, too few cells of the coarser
    DEM); the vertical offset and the tilt alone can still be fitted (CoregParams.horizontal off)."""


@dataclass(frozen=True)
class CoregParams:
    """The co-registration's settings (pushbroom:coregisterdem's parameters)."""

    dem_heights: str = "ellipsoidal"  # control_points.HEIGHT_TYPES
    reference_heights: str = "ellipsoidal"
    reference_nodata: float | None = None  # a void value of the reference its file does not flag
    mask: str | None = None  # unstable terrain: a raster whose non-zero cells are left out
    max_slope: float = 40.0  # degrees of the reference: steeper cells are left out
    outlier_nmad: float = 3.0  # |dh - median| beyond this many NMADs is left out
    tilt: bool = False  # fit a plane besides the shift
    horizontal: bool = True  # fit the horizontal shift (off: the vertical offset and the tilt only)
    tolerance: float = 0.005  # cells: the horizontal increment at which the iterations stop
    max_iterations: int = 30
    execution: Execution = field(default_factory=Execution)

    def check(self) -> CoregParams:
        """Raise InputError for settings no co-registration can use."""
        if not 0 < self.max_slope < 90:
            raise InputError(f"the largest slope must be between 0 and 90 degrees, not {self.max_slope}")
        if not self.outlier_nmad > 0 or not self.tolerance > 0 or self.max_iterations < 1:
            raise InputError("the outlier bound and the tolerance must be positive and the iterations at least one")
        self.execution.check()
        return self


@dataclass(frozen=True)
class Shift:
    """What co-registration does to the DEM: its grid moved by (east, north) m, then `up` m plus a plane of slopes
    (tilt_east, tilt_north) m/m about `centre` (the DEM's centre, in its CRS) added to its heights."""

    east: float = 0.0
    north: float = 0.0
    up: float = 0.0
    tilt_east: float = 0.0
    tilt_north: float = 0.0
    centre: tuple[float, float] = (0.0, 0.0)

    def describe(self, cell: float) -> str:
        """One line: the shift in m and in cells of `cell` m, the tilt where there is one."""
        text = (
            f"east {self.east:+.3f} m, north {self.north:+.3f} m ({self.east / cell:+.3f}, {self.north / cell:+.3f} "
            f"cells), up {self.up:+.3f} m"
        )
        if self.tilt_east or self.tilt_north:
            text += f", tilt east {self.tilt_east:+.2e}, north {self.tilt_north:+.2e}"
        return text

    def moved(self, geotransform: tuple[float, ...], units: tuple[float, float]) -> tuple[float, ...]:
        """The geotransform of a grid moved by the (east, north) m of the shift, `units` m per CRS unit."""
        x0, dx, _, y0, _, dy = geotransform
        return (x0 + self.east / units[0], dx, 0.0, y0 + self.north / units[1], 0.0, dy)

    def vertical(self, x: np.ndarray, y: np.ndarray, units: tuple[float, float]) -> np.ndarray:
        """The vertical correction at the moved cells' centres (x, y in the DEM's CRS; `units` m per CRS unit)."""
        de, dn = (x - self.centre[0]) * units[0], (y - self.centre[1]) * units[1]
        return self.up + self.tilt_east * de + self.tilt_north * dn


@dataclass(frozen=True)
class _Frame:
    """The DEM's grid and its metric scale: `units` (east, north) metres per CRS unit, `cell` m (the mean side)."""

    path: str
    geotransform: tuple[float, ...]
    size: tuple[int, int]  # cols, rows
    srs_wkt: str
    units: tuple[float, float]

    @property
    def cell(self) -> float:
        return 0.5 * (abs(self.geotransform[1]) * self.units[0] + abs(self.geotransform[5]) * self.units[1])


@dataclass(frozen=True)
class _Pass:
    """One pass over the windows: the DEM as co-registered by `shift`; the stable cells' dh within `bound` of
    `median` (None: the first read of an iteration, which only summarises dh)."""

    frame: _Frame
    reference: Reference
    params: CoregParams
    shift: Shift
    resampling: str  # of the reference onto the DEM's cells (height_differences.resampling_onto)
    median: float | None = None
    bound: float | None = None


@dataclass
class _Sums:
    """A window's contribution: the normal equations of the increments and the summary of its stable dh."""

    normals: np.ndarray
    rhs: np.ndarray
    squares: float  # sum of dh^2 over the fitted cells
    summary: DhSummary

    def add(self, other: _Sums) -> _Sums:
        return _Sums(
            self.normals + other.normals,
            self.rhs + other.rhs,
            self.squares + other.squares,
            self.summary.merge(other.summary),
        )


@dataclass(frozen=True)
class CoregResult:
    """The shift found, its iterations and the stable cells' dh statistics before and after (statistics.Stats)."""

    shift: Shift
    cell: float  # m, the DEM's mean cell side
    iterations: int
    before: Any
    after: Any
    resampling: str  # how the reference met the DEM's cells
    history: list[Shift]
    units: tuple[float, float]  # m per unit of the DEM's CRS, east and north
    sigma: tuple[float, float, float]  # m: standard errors of the shift east, north and up (module docstring)


def _frame(path: str | os.PathLike[str], datum: str) -> _Frame:
    ds = open_raster(path, "DEM")
    check_stated(ds, datum, "DEM", path)
    srs, gt = raster_srs(ds), ds.GetGeoTransform()
    units = metres_per_unit(gt, srs, ds.RasterYSize)
    return _Frame(str(path), tuple(gt), (ds.RasterXSize, ds.RasterYSize), srs.ExportToWkt(), units)


def _moved(frame: _Frame, shift: Shift, window: tuple[int, int, int, int], margin: int) -> Grid:
    """The empty Grid of the DEM's `window` cells and `margin` more around, its grid moved by `shift`."""
    c0, r0, c1, r1 = window
    x0, dx, _, y0, _, dy = frame.geotransform
    gt = shift.moved((x0 + (c0 - margin) * dx, dx, 0.0, y0 + (r0 - margin) * dy, 0.0, dy), frame.units)
    return Grid(np.empty((r1 - r0 + 2 * margin, c1 - c0 + 2 * margin)), gt, parse_crs(frame.srs_wkt))


def window_sums(job: _Pass, window: tuple[int, int, int, int]) -> _Sums:
    """The _Sums of one window of the DEM (module docstring); a task of run_tasks."""
    frame, params, shift = job.frame, job.params, job.shift
    k = 2 * params.horizontal + 1 + 2 * params.tilt
    empty = _Sums(np.zeros((k, k)), np.zeros(k), 0.0, DhSummary())
    source = open_raster(frame.path, "DEM")
    dem = read_grid(source, window=window).values
    if not np.isfinite(dem).any():
        return empty
    check_cancel()
    ds = open_raster(job.reference.path, "reference DEM")
    wide = _moved(frame, shift, window, 1)
    reach = ReferenceReach(job.reference.path, job.reference.nodata)
    ref = reference_on_grid(ds, wide, job.reference.nodata, reach, job.resampling)
    if not np.isfinite(ref).any():
        return empty
    x, y = wide.centres()
    # the heights in one datum: where the two differ, the EGM96 undulation N (on a lattice: crs.undulation_rows)
    # moves the orthometric ones; where they agree, N would cancel in dh
    if params.dem_heights != job.reference.datum:
        n = undulation_rows(ref.shape, wide.geotransform, wide.srs)(0, ref.shape[0])
        ref = ref + n if job.reference.datum == "orthometric" else ref - n
    g_e, g_n = gradient(Grid(ref, wide.geotransform, wide.srs))  # the reference's, in m/m
    inner = (slice(1, -1), slice(1, -1))
    ref, g_e, g_n, x, y = ref[inner], g_e[inner], g_n[inner], x[inner], y[inner]
    dh = dem + shift.vertical(x, y, frame.units) - ref  # in the DEM's datum
    stable = np.isfinite(dh) & np.isfinite(g_e) & np.isfinite(g_n)
    stable &= np.degrees(np.arctan(np.hypot(g_e, g_n))) <= params.max_slope
    if params.mask:
        stable &= ~_unstable(params.mask, Grid(dh, _moved(frame, shift, window, 0).geotransform, wide.srs))
    check_cancel()
    if job.median is None:
        return replace(empty, summary=DhSummary.of(dh[stable]))
    stable &= np.abs(dh - job.median) <= job.bound
    columns = [g_e[stable], g_n[stable]] if params.horizontal else []
    columns.append(np.ones(int(stable.sum())))
    if params.tilt:
        columns += [(x[stable] - shift.centre[0]) * frame.units[0], (y[stable] - shift.centre[1]) * frame.units[1]]
    a, b = np.column_stack(columns), dh[stable]
    return _Sums(a.T @ a, a.T @ b, float(b @ b), DhSummary.of(b))


def _unstable(mask: str, grid: Grid) -> np.ndarray:
    """The cells of `grid` the unstable-terrain raster `mask` covers with a non-zero value (nearest cell; cells it
    does not reach are stable)."""
    values = warp_to(open_raster(mask, "unstable terrain mask"), grid, "near")
    return np.isfinite(values) & (values != 0)


def _pass(job: _Pass, windows: list[tuple[int, int, int, int]], feedback: Feedback | None) -> _Sums:
    sums = run_tasks(
        window_sums, [(job, w) for w in windows], job.params.execution, feedback, "co-registration windows"
    )
    total = sums[0]
    for s in sums[1:]:
        total = total.add(s)
    return total


def _enough(n: int, frame: _Frame, reference: Reference) -> None:
    """InputError unless `n` stable cells are enough to fit."""
    if n == 0:
        raise InputError(
            f"the reference DEM {reference.path} does not overlap the DEM {frame.path} on stable terrain (or holds "
            "only nodata there): choose a reference that covers it, or a smaller unstable mask"
        )
    if n < MIN_CELLS:
        raise InputError(
            f"only {n} stable cells where the DEM {frame.path} and the reference overlap (at least {MIN_CELLS} are "
            "needed): give a larger overlap, a larger largest slope or a smaller unstable mask"
        )


def _increments(total: _Sums, params: CoregParams, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """The fitted increments (d_e, d_n, d_z[, p_e, p_n]; d_e, d_n zero without the horizontal shift) and their
    covariance, sigma_0^2 N^-1 times `factor` (the DEM cells per cell of a coarser reference: its residuals are
    correlated over a reference cell). InputError where the terrain does not show the horizontal shift."""
    normals, k = total.normals, total.rhs.size
    if params.horizontal:
        schur: np.ndarray = normals[:2, :2] - normals[:2, 2:] @ np.linalg.solve(normals[2:, 2:], normals[2:, :2])
        if not np.linalg.eigvalsh(schur)[0] > 1e-9 * max(np.trace(normals[:2, :2]), 1e-300):
            raise ShiftNotShownError(
                "the stable terrain is flat, or all its slopes face one way: it shows no horizontal shift. Co-register "
                "the vertical offset (and the tilt) only, or give a larger area or fewer unstable cells"
            )
    try:
        x = np.linalg.solve(normals, total.rhs)
        inverse = np.linalg.inv(normals)
    except np.linalg.LinAlgError:
        raise InputError(
            "the stable cells do not fix the co-registration's unknowns (the tilt needs cells spread over the DEM): "
            "co-register without the tilt, or give more stable terrain"
        ) from None
    sigma2 = max(total.squares - float(x @ total.rhs), 0.0) / max(total.summary.n - k, 1)
    covariance = sigma2 * factor * inverse
    if not params.horizontal:
        x, covariance = np.concatenate([[0.0, 0.0], x]), _padded(covariance)
    return x, covariance


def _padded(covariance: np.ndarray) -> np.ndarray:
    """The covariance of the vertical terms with zero rows and columns for a horizontal shift held at zero."""
    out = np.zeros((covariance.shape[0] + 2,) * 2)
    out[2:, 2:] = covariance
    return out


def _determined(covariance: np.ndarray, cell: float, shift: Shift) -> None:
    """InputError where the horizontal shift's standard error (the larger semi-axis of its error ellipse) exceeds
    MAX_SIGMA cells of `cell` m."""
    sigma = math.sqrt(max(np.linalg.eigvalsh(covariance[:2, :2])[-1], 0.0))
    if sigma > MAX_SIGMA * cell:
        raise ShiftNotShownError(
            f"the stable terrain does not show the horizontal shift: its standard error would be {sigma:.1f} m "
            f"({sigma / cell:.2f} of a {cell:.0f} m cell; the fit reached {shift.describe(cell)}). The slopes face one "
            "way, or the area spans few cells of the coarser DEM: co-register the vertical offset (and the tilt) "
            "only, or give a larger area"
        )


def _reference_cell(reference: Reference, frame: _Frame) -> tuple[float, str]:
    """(the reference's mean cell side in m where the DEM lies, its resampling onto the DEM's cells:
    resampling_onto). A geographic reference's cells are measured at the DEM's centre latitude (a continental mosaic's
    own centre may lie far from it). The rasters are closed on return: a GDAL dataset left in a frame that an
    exception's traceback keeps may be freed after QGIS has shut GDAL down."""
    ds, source = open_raster(reference.path, "reference DEM"), open_raster(frame.path, "DEM")
    srs, gt = raster_srs(ds), ds.GetGeoTransform()
    if srs.IsGeographic():
        x0, dx, _, y0, _, dy = frame.geotransform
        centre = (x0 + 0.5 * frame.size[0] * dx, y0 + 0.5 * frame.size[1] * dy)
        lat = float(reproject(np.array([centre[0]]), np.array([centre[1]]), parse_crs(frame.srs_wkt), srs)[1][0])
        east, north = metres_per_degree(lat)
        cell = math.sqrt(abs(gt[1]) * float(east) * abs(gt[5]) * float(north))
    else:
        cell = math.sqrt(np.prod(cell_metres(gt, srs, ds.RasterYSize)))
    return cell, resampling_onto(ds, source)


def coregister_or_vertical(
    dem: str | os.PathLike[str], reference: Reference, params: CoregParams, feedback: Feedback | None = None
) -> CoregResult:
    """coregister; where the terrain does not show the horizontal shift (ShiftNotShownError), the vertical offset
    (and the tilt) alone, with a warning saying so. Raises what coregister raises otherwise."""
    try:
        return coregister(dem, reference, params, feedback)
    except ShiftNotShownError as exc:  # raised only where the horizontal shift is fitted
        progress.warn(feedback, f"{dem}: {exc}. It is co-registered by its vertical offset only")
        return coregister(dem, reference, replace(params, horizontal=False), feedback)


def coregister(
    dem: str | os.PathLike[str],
    reference: Reference,
    params: CoregParams,
    feedback: Feedback | None = None,
) -> CoregResult:
    """The Shift that brings the DEM raster `dem` onto the Reference `reference` over stable terrain, with
    CoregParams `params` (module docstring). Raises InputError, CoregistrationError, CancelledError."""
    params.check()
    frame = _frame(dem, params.dem_heights)
    check_stated(open_raster(reference.path, "reference DEM"), reference.datum, "reference DEM", reference.path)
    x0, dx, _, y0, _, dy = frame.geotransform
    shift, history = Shift(centre=(x0 + 0.5 * frame.size[0] * dx, y0 + 0.5 * frame.size[1] * dy)), []
    windows, before, d = tile_grid(frame.size, WINDOW), None, np.zeros(3)
    reference_cell, method = _reference_cell(reference, frame)
    cell = max(frame.cell, reference_cell)  # the cell whose heights are independent
    factor = max(reference_cell**2 / frame.cell**2, 1.0)
    for k in range(params.max_iterations):
        span = 100.0 / (params.max_iterations + 1)
        job = _Pass(frame, reference, params, shift, method)
        first = _pass(job, windows, progress.scaled(feedback, k * span, (k + 0.5) * span))
        stats = first.summary.stats()
        if before is None:
            before = stats
        _enough(stats.n, frame, reference)
        bound = params.outlier_nmad * max(stats.nmad, 1e-3)
        total = _pass(
            replace(job, median=stats.median, bound=bound),
            windows,
            progress.scaled(feedback, (k + 0.5) * span, (k + 1) * span),
        )
        _enough(total.summary.n, frame, reference)
        d, covariance = _increments(total, params, factor)
        tilt = d[3:] if params.tilt else np.zeros(2)
        shift = replace(
            shift,
            east=shift.east + d[0],
            north=shift.north + d[1],
            up=shift.up - d[2],
            tilt_east=shift.tilt_east - tilt[0],
            tilt_north=shift.tilt_north - tilt[1],
        )
        history.append(shift)
        converged = math.hypot(d[0], d[1]) < params.tolerance * frame.cell and abs(d[2]) < TOLERANCE_UP
        if params.horizontal and (k or converged):  # the first fit's residuals hold its linearisation's misfit
            _determined(covariance, cell, shift)
        progress.ensure(feedback).pushInfo(
            f"co-registration, iteration {k + 1}: {shift.describe(frame.cell)}; {total.summary.n} stable cells"
        )
        if converged:
            after = _pass(_Pass(frame, reference, params, shift, method), windows, None).summary.stats()
            progress.step(feedback, 100)
            se, sn, su = (math.sqrt(max(float(covariance[i, i]), 0.0)) for i in range(3))
            return CoregResult(shift, frame.cell, k + 1, before, after, method, history, frame.units, (se, sn, su))
    last = history[-1]
    raise CoregistrationError(
        f"the co-registration of {frame.path} did not converge in {params.max_iterations} iterations: the last shift "
        f"was {last.describe(frame.cell)}, still moving by {math.hypot(d[0], d[1]):.3f} m. The DEM and the reference "
        "may differ by more than a shift (check the stable terrain, the mask and the largest slope)"
    )
