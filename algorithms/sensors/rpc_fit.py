"""RPC00B fitted to any sensor model over a terrain-independent cube (Kornus et al. 2006, section 3.5.2).

Points: the cube, an image grid (default 11 x 11 over the whole image, pixel edges 0 .. cols,
0 .. rows) times height levels (default 11 over the height range), ground positions from the
model's image_to_ground; the selection points, the centres of the cube's cells; the validation
points, a grid twice as dense as the cube shifted by half its step (a quarter of a cube cell), over
the same image and heights. Offsets and scales are the middles and half ranges of the cube's
coordinates (image coordinates in RPC00B's convention, first pixel centre at 0: samp = col - 0.5).

Each normalised image coordinate v = num(L, P, H) / den(L, P, H) (rpc.py) is fitted to the cube by
the linearised equations

    num . t - v (den . t) = 0,   den_0 = 1,   t = the 20 RPC00B terms of (L, P, H),

in least squares with weights 1 / den^2 from the previous iteration (so the weighted residual is
the image residual; den = 1 at the start), iterated until den settles. On a nearly affine mapping
the denominator terms are nearly collinear with the numerator's, so the denominator is damped by
Tikhonov regularisation, lambda * |den_1..19|^2 with lambda = r * trace(N) / 39 (N the weighted
normal matrix); the system is solved in its augmented form [A; sqrt(lambda) D] x = [b; 0] by SVD,
so its conditioning is not squared. r runs over a ladder (REGULARISATIONS, or the one value given);
a candidate whose denominator comes near zero over the points (a change of sign, or min |den| below
MIN_DEN_RATIO max |den|) or changes sign anywhere on the grid of the validity domain that every RPC
reader checks (rpc.domain_grid) is rejected, and a plain cubic polynomial (den = 1, the paper's
fallback for the nadir image) is always a candidate, so a fitted RPC always reads back. Of the
candidates, the one with the smallest RMS on the selection points is kept, per image coordinate;
the validation points take no part in that choice (only a candidate whose denominator nears zero
there too is rejected), so their errors are independent.

surface.intersection.height_differences compares object points intersected with the RPCs and with
the rigorous models (Kornus et al. 2006, Table 5)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from .. import progress
from ..errors import GeometryError, InputError, PushbroomError
from ..progress import Feedback
from . import rpc_io
from .base import SensorModel
from .rpc import NUM_TERMS, RpcCoefficients, RpcModel, domain_grid, keeps_sign, rpc_terms

#: a fitted coordinate: numerator and denominator coefficients, the damping factor (None: the cubic polynomial)
#: and the reweighting iterations
Candidate = tuple[np.ndarray, np.ndarray, float | None, int]

#: default cube: image grid columns x rows x height levels
DEFAULT_GRID = (11, 11, 11)
#: denominator damping factors tried (relative to the mean diagonal of the normal matrix)
REGULARISATIONS = (1e-14, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2)
#: a denominator whose smallest |value| over the points is below this share of its largest is near a pole
MIN_DEN_RATIO = 0.1
MAX_ITERATIONS = 20
#: the reweighting stops when the denominator (1 at the normalisation centre) changes less than this
DEN_TOL = 1e-6
#: the default height range is the terrain's widened by this share of its span on either side,
#: and by at least MIN_HEIGHT_MARGIN metres
HEIGHT_MARGIN = 0.1
MIN_HEIGHT_MARGIN = 100.0


@dataclass(frozen=True)
class AxisErrors:
    """RMS and maximum |error| (px) of one image coordinate."""

    rms: float
    max: float

    @classmethod
    def of(cls, diff: np.ndarray) -> AxisErrors:
        return cls(float(np.sqrt(np.mean(diff * diff))), float(np.max(np.abs(diff))))


@dataclass(frozen=True)
class AxisFit:
    """How one image coordinate was fitted, and its errors (px) on the cube and validation points."""

    cube: AxisErrors
    validation: AxisErrors
    #: None for the cubic polynomial, else the damping factor r of the rational fit kept
    regularisation: float | None
    #: rational candidates tried, and rejected for a denominator near zero
    rational_fits: int
    near_pole: int
    #: reweighting iterations of the fit kept (0 for the polynomial)
    iterations: int

    @property
    def polynomial(self) -> bool:
        return self.regularisation is None

    def describe(self) -> str:
        if not self.polynomial:
            return f"rational 3/3 (r = {self.regularisation:.0e}, {self.iterations} reweightings)"
        return (
            f"cubic polynomial ({self.near_pole} of {self.rational_fits} rational fits had a denominator near zero)"
            if self.near_pole
            else "cubic polynomial (fits best)"
        )


@dataclass(frozen=True)
class RpcFitReport:
    """Fit (cube) and validation errors of a fitted RPC against the model it was fitted to."""

    cube_points: int
    validation_points: int
    height_range: tuple[float, float]
    col: AxisFit
    row: AxisFit

    @property
    def polynomial(self) -> tuple[str, ...]:
        """The image coordinates ("col", "row") fitted as plain cubic polynomials."""
        return tuple(name for name in ("col", "row") if getattr(self, name).polynomial)

    @property
    def max_error(self) -> float:
        """Largest |error| (px) of either coordinate on the cube and the validation points."""
        return max(e.max for a in (self.col, self.row) for e in (a.cube, a.validation))

    def summary(self) -> str:
        """One line: per coordinate the kind of fit and its RMS / max errors on both point sets."""
        parts = [
            f"{name}: {a.describe()}, cube RMS {a.cube.rms:.2e} max {a.cube.max:.2e} px, validation RMS "
            f"{a.validation.rms:.2e} max {a.validation.max:.2e} px"
            for name, a in (("col", self.col), ("row", self.row))
        ]
        return (
            f"{self.cube_points} cube / {self.validation_points} validation points, heights "
            f"{self.height_range[0]:.0f} .. {self.height_range[1]:.0f} m; " + "; ".join(parts)
        )


def _grid(lo: float, hi: float, n: int, kind: str) -> np.ndarray:
    """n values from lo to hi ('cube'), the n - 1 cell centres ('selection'), or 2 (n - 1) values
    in the middles of a grid twice as dense ('validation')."""
    if kind == "cube":
        return np.linspace(lo, hi, n)
    k = (n - 1) * (2 if kind == "validation" else 1)
    return lo + (np.arange(k) + 0.5) * (hi - lo) / k


def _points(
    model: SensorModel, height_range: tuple[float, float], grid: Sequence[int], kind: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Image points (col, row), heights and ground (lon, lat) of a point set (see _grid)."""
    cols, rows = model.size
    axes = [
        _grid(0.0, cols, grid[0], kind),
        _grid(0.0, rows, grid[1], kind),
        _grid(height_range[0], height_range[1], grid[2], kind),
    ]
    col, row, h = (a.ravel() for a in np.meshgrid(*axes, indexing="ij"))
    try:
        lon, lat = model.image_to_ground(col, row, h)
    except GeometryError as exc:
        raise InputError(
            f"cannot fit an RPC: the sensor model has no ground position over the whole image and height range ({exc})"
        ) from exc
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    bad = ~(np.isfinite(lon) & np.isfinite(lat))
    if bad.any():
        i = np.flatnonzero(bad)[0]
        raise InputError(
            f"cannot fit an RPC: the sensor model gives no ground position for {bad.sum()} of "
            f"{bad.size} image points, e.g. ({col[i]:.1f}, {row[i]:.1f}) at {h[i]:.1f} m; is its "
            f"orientation complete for the whole image ({cols} x {rows} px) and the height range "
            f"{height_range[0]:.0f} .. {height_range[1]:.0f} m plausible?"
        )
    return col, row, h, lon, lat


def _mid_half(values: np.ndarray) -> tuple[float, float]:
    lo, hi = float(np.min(values)), float(np.max(values))
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def _near_pole(den: np.ndarray) -> bool:
    """Whether a denominator (its values over the points) changes sign or comes near zero."""
    return not np.all(np.isfinite(den)) or np.min(den) <= 0.0 or np.min(den) < MIN_DEN_RATIO * np.max(den)


def _fit_rational(
    t: np.ndarray, v: np.ndarray, r: float, checks: tuple[np.ndarray, ...]
) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(num, den, iterations) of v = num.t / den.t by reweighted, denominator-damped least squares
    (module docstring); None where the denominator comes near zero on t or any of `checks`, or changes
    sign on the validity domain's grid."""
    domain = rpc_terms(*domain_grid())
    a = np.hstack([t, -v[:, None] * t[:, 1:]])
    damping = np.hstack([np.zeros((NUM_TERMS - 1, NUM_TERMS)), np.eye(NUM_TERMS - 1)])
    den = np.ones(v.size)
    for iteration in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (the count is returned)
        aw = a / den[:, None]
        lam = r * float(np.sum(aw * aw)) / aw.shape[1]
        x = np.linalg.lstsq(
            np.vstack([aw, math.sqrt(lam) * damping]), np.concatenate([v / den, np.zeros(NUM_TERMS - 1)]), rcond=None
        )[0]
        coef = np.concatenate([[1.0], x[NUM_TERMS:]])
        if any(_near_pole(c @ coef) for c in (t,) + checks) or not keeps_sign(domain @ coef):
            return None
        previous, den = den, t @ coef
        if np.max(np.abs(den - previous)) < DEN_TOL:
            break
    return x[:NUM_TERMS], coef, iteration


def _fit_axis(
    t: np.ndarray,
    v: np.ndarray,
    t_select: np.ndarray,
    v_select: np.ndarray,
    t_validation: np.ndarray,
    regularisations: Sequence[float],
) -> tuple[np.ndarray, np.ndarray, float | None, int, int, int]:
    """(num, den, regularisation or None, rational fits tried, near-pole count, iterations) of one
    normalised image coordinate: the candidate with the smallest RMS at the selection points."""
    unit = np.zeros(NUM_TERMS)
    unit[0] = 1.0
    candidates: list[Candidate] = [(np.linalg.lstsq(t, v, rcond=None)[0], unit, None, 0)]
    near_pole = 0
    for r in regularisations:
        fit = _fit_rational(t, v, r, (t_select, t_validation))
        if fit is None:
            near_pole += 1
        else:
            candidates.append((fit[0], fit[1], r, fit[2]))

    def mean_square(candidate: Candidate) -> float:
        num, den = candidate[:2]
        return float(np.mean((t_select @ num / (t_select @ den) - v_select) ** 2))

    num, den, kept, iterations = min(candidates, key=mean_square)
    return num, den, kept, len(regularisations), near_pole, iterations


def fit_rpc(
    model: SensorModel,
    height_range: Sequence[float],
    grid: Sequence[int] = DEFAULT_GRID,
    regularisation: float | None = None,
    feedback: Feedback | None = None,
) -> tuple[RpcModel, RpcFitReport]:
    """(RpcModel, RpcFitReport): an RPC00B (degree 3/3) fitted to `model` over its whole image and
    `height_range` (min, max ellipsoidal heights, m) on a cube of grid = (columns, rows, heights)
    points (module docstring); `regularisation` fixes the denominator damping factor r (default:
    chosen per coordinate from REGULARISATIONS). RpcModel(coefficients, size=model.size) reproduces
    model.ground_to_image in GDAL's pixel convention."""
    lo, hi = (float(v) for v in height_range)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise InputError(
            f"cannot fit an RPC over the heights {lo} .. {hi} m: give two numbers of metres (e.g. the "
            "terrain's range plus a margin)"
        )
    if hi <= lo:
        raise InputError(
            f"cannot fit an RPC: the lowest height of its cube ({lo:g} m) is "
            f"{'above' if lo > hi else 'the same as'} the highest ({hi:g} m); give the lowest first, "
            "below the highest (e.g. the terrain's range plus a margin)"
        )
    grid = tuple(int(g) for g in grid)
    if len(grid) != 3 or min(grid) < 4:
        raise InputError(
            f"the RPC cube grid {grid} needs 3 sizes (columns, rows, heights) of at least 4 each: "
            "a cubic needs 4 values per axis"
        )
    if min(model.size) <= 0:
        raise InputError(f"cannot fit an RPC to an image of size {model.size}")
    regularisations = REGULARISATIONS if regularisation is None else (float(regularisation),)
    progress.step(
        feedback, 0.0, f"RPC cube of {grid[0]} x {grid[1]} x {grid[2]} points, heights {lo:.0f} .. {hi:.0f} m"
    )
    sets = {kind: _points(model, (lo, hi), grid, kind) for kind in ("cube", "selection", "validation")}
    col, row, h, lon, lat = sets["cube"]
    (long_off, long_scale), (lat_off, lat_scale), (h_off, h_scale), (samp_off, samp_scale), (line_off, line_scale) = (
        _mid_half(v) for v in (lon, lat, h, col - 0.5, row - 0.5)
    )
    if min(long_scale, lat_scale) <= 0.0:
        raise InputError("cannot fit an RPC: the sensor model maps the whole image to one ground point")
    t = {
        k: rpc_terms((p[3] - long_off) / long_scale, (p[4] - lat_off) / lat_scale, (p[2] - h_off) / h_scale)
        for k, p in sets.items()
    }
    fitted: dict[str, tuple[np.ndarray, np.ndarray, float | None, int, int, int]] = {}
    for k, (name, offset, scale) in enumerate((("samp", samp_off, samp_scale), ("line", line_off, line_scale))):
        progress.step(feedback, 20.0 + 35.0 * k)
        v = {kind: (p[k] - 0.5 - offset) / scale for kind, p in sets.items()}
        fitted[name] = _fit_axis(t["cube"], v["cube"], t["selection"], v["selection"], t["validation"], regularisations)
    coefficients = RpcCoefficients.from_fields(
        {
            "LINE_NUM_COEFF": fitted["line"][0],
            "LINE_DEN_COEFF": fitted["line"][1],
            "SAMP_NUM_COEFF": fitted["samp"][0],
            "SAMP_DEN_COEFF": fitted["samp"][1],
            "LINE_OFF": line_off,
            "SAMP_OFF": samp_off,
            "LAT_OFF": lat_off,
            "LONG_OFF": long_off,
            "HEIGHT_OFF": h_off,
            "LINE_SCALE": line_scale,
            "SAMP_SCALE": samp_scale,
            "LAT_SCALE": lat_scale,
            "LONG_SCALE": long_scale,
            "HEIGHT_SCALE": h_scale,
        },
        "fitted RPC",
    )
    rpc = RpcModel(coefficients, size=model.size, source="fitted RPC")
    progress.step(feedback, 90.0)
    errors: dict[str, tuple[AxisErrors, AxisErrors]] = {}
    for kind in ("cube", "validation"):
        c, r, hh, x, y = sets[kind]
        fc, fr = rpc.ground_to_image(x, y, hh)
        errors[kind] = (AxisErrors.of(fc - c), AxisErrors.of(fr - r))
    axes = [
        AxisFit(errors["cube"][k], errors["validation"][k], *fitted[name][2:])
        for k, name in enumerate(("samp", "line"))
    ]
    report = RpcFitReport(col.size, sets["validation"][0].size, (lo, hi), *axes)
    progress.step(feedback, 100.0, report.summary())
    return rpc, report


def default_height_range(terrain_range: Sequence[float]) -> tuple[float, float]:
    """(min, max) heights for the cube: the terrain height range widened by HEIGHT_MARGIN of its span,
    at least MIN_HEIGHT_MARGIN m, on either side."""
    lo, hi = (float(v) for v in terrain_range)
    margin = max(MIN_HEIGHT_MARGIN, HEIGHT_MARGIN * (hi - lo))
    return lo - margin, hi + margin


def rpc_txt_path(
    image_path: str | os.PathLike[str], folder: str | os.PathLike[str] | None = None, name: str | None = None
) -> str:
    """Where an image's fitted RPC goes: beside the raster as <stem>_RPC.TXT, GDAL's own naming, so
    GDAL reads it with the raster; or in `folder` as <name (default: the raster's stem)>_RPC.TXT."""
    if folder is None:
        stem = os.path.splitext(os.path.abspath(os.fspath(image_path)))[0]
        return f"{stem}_RPC.TXT"
    return os.path.join(os.fspath(folder), f"{name or os.path.splitext(os.path.basename(image_path))[0]}_RPC.TXT")


def check_destination(path: str | os.PathLike[str], overwrite: bool = False) -> None:
    """Refuse an existing file, such as the RPC an image came with, unless `overwrite` is true."""
    if os.path.exists(path) and not overwrite:
        raise InputError(
            f"{path} exists already (the RPC the image came with, or an earlier fit); set the "
            "overwrite option to replace it, or write the fitted RPCs to an output folder"
        )


def write_fitted_rpc(rpc: RpcModel, path: str | os.PathLike[str], overwrite: bool = False) -> str:
    """Write `rpc` as a _RPC.TXT (rpc_io.write_rpc_txt, atomic) after check_destination; returns the path."""
    path = os.fspath(path)
    check_destination(path, overwrite)
    try:
        rpc_io.write_rpc_txt(rpc, path)
    except OSError as exc:
        raise InputError(
            f"cannot write {path} ({exc.strerror}); write the fitted RPCs to an output folder you may write to"
        ) from exc
    return path


def raster_reads(raster: str | os.PathLike[str], rpc: RpcModel) -> bool:
    """Whether GDAL, opening `raster`, finds the RPC of `rpc` (coefficients and offsets to 1e-12
    relative); a raster may carry other RPC that GDAL prefers, or none."""
    try:
        found = RpcCoefficients.from_fields(rpc_io.read_raster(raster).fields, os.fspath(raster))
    except PushbroomError:
        return False
    mine = rpc.coefficients
    return all(np.allclose(getattr(found, f.name), getattr(mine, f.name), rtol=1e-12, atol=0.0) for f in fields(mine))


def raster_rpc_source(raster: str | os.PathLike[str]) -> str | None:
    """Where GDAL, opening `raster`, finds an RPC of its own: the .RPB or _RPC.TXT beside it that it reads
    (these come before the raster's metadata), else "the metadata of <raster>" (GeoTIFF RPC tags, a NITF
    segment, an .aux.xml); None where it finds none or cannot open the raster."""
    from osgeo import gdal

    gdal.UseExceptions()
    try:
        ds = gdal.Open(os.fspath(raster))
    except RuntimeError:
        return None
    if not ds.GetMetadata("RPC"):
        return None
    return rpc_io.rpc_sidecar(ds) or f"the metadata of {raster}"


def report_text(entries: Sequence[tuple[str, str, RpcFitReport]]) -> str:
    """A text table of fit and validation errors (px), one row per image coordinate: `entries` are
    (image name, RPC file written, RpcFitReport)."""
    lines = [f"{'image':12} {'coord':5} {'cube RMS':>9} {'cube max':>9} {'valid RMS':>9} {'valid max':>9}  fit"]
    for name, _path, r in entries:
        for axis, a in (("col", r.col), ("row", r.row)):
            lines.append(
                f"{name:12} {axis:5} {a.cube.rms:9.2e} {a.cube.max:9.2e} {a.validation.rms:9.2e} "
                f"{a.validation.max:9.2e}  {a.describe()}"
            )
    lines.append("")
    lines += [
        f"{name}: {r.cube_points} cube points, {r.validation_points} validation points, heights "
        f"{r.height_range[0]:.0f} .. {r.height_range[1]:.0f} m -> {path}"
        for name, path, r in entries
    ]
    return "\n".join(lines)
