"""RPC00B fitted to any sensor model over a terrain-independent cube (paper K 3.5.2, methods.md 5).

Cube: an image grid (default 11 x 11 over the whole image, pixel edges 0 .. cols, 0 .. rows) times
height levels (default 11 over the height range); the ground points come from the model's
image_to_ground. Offsets and scales are the middles and half ranges of the cube's coordinates
(image coordinates in RPC00B's convention, first pixel centre at 0: samp = col - 0.5).

Each normalised image coordinate v = num(L, P, H) / den(L, P, H) (rpc.py) is fitted by the
linearised equations

    num . t - v (den . t) = 0,   den_0 = 1,   t = the 20 RPC00B terms of (L, P, H),

in least squares with weights 1 / den^2 from the previous iteration (so the weighted residual is
the image residual; den = 1 at the start), iterated until den settles. Tikhonov regularisation
lambda = regularisation * trace(N) / 39 (N = the weighted normal matrix) keeps the solution
defined where terms are nearly collinear (a small scene is almost affine); the system is solved
in its augmented form [A; sqrt(lambda) I] x = [b; 0] by SVD, so conditioning is not squared.
Where a denominator comes near zero over the cube or the validation points (min |den| below
MIN_DEN_RATIO max |den|, or a change of sign), that coordinate falls back to a plain cubic
polynomial (den = 1), as the paper did for the nadir image. Validation: a grid twice as dense,
shifted by half its step, over the same image and height range."""
import html
import math
import os
from dataclasses import dataclass, fields

import numpy as np

from .. import progress
from ..errors import GeometryError, InputError, PushbroomError
from . import rpc_io
from .rpc import NUM_TERMS, RpcCoefficients, RpcModel

#: default cube: image grid columns x rows x height levels
DEFAULT_GRID = (11, 11, 11)
#: Tikhonov factor relative to the mean diagonal of the normal matrix
DEFAULT_REGULARISATION = 1e-8
#: a denominator whose smallest |value| over the domain is below this share of its largest is near a pole
MIN_DEN_RATIO = 0.1
MAX_ITERATIONS = 20
#: the default height range is the terrain's widened by this share of its span on either side,
#: and by at least MIN_HEIGHT_MARGIN metres
HEIGHT_MARGIN = 0.1
MIN_HEIGHT_MARGIN = 100.0
#: the reweighting stops when the denominator (1 at the normalisation centre) changes less than this
DEN_TOL = 1e-6


def rpc_terms(x, y, z):
    """(n, 20) RPC00B terms 1 L P H LP LH PH L^2 P^2 H^2 PLH L^3 LP^2 LH^2 L^2P P^3 PH^2 L^2H P^2H H^3
    of normalised x = L, y = P, z = H (the order of rpc._poly)."""
    return np.column_stack([np.ones_like(x), x, y, z, x * y, x * z, y * z, x * x, y * y, z * z,
                            x * y * z, x ** 3, x * y * y, x * z * z, x * x * y, y ** 3, y * z * z,
                            x * x * z, y * y * z, z ** 3])


@dataclass(frozen=True)
class AxisErrors:
    """RMS and maximum |error| (px) of one image coordinate."""
    rms: float
    max: float

    @classmethod
    def of(cls, diff):
        return cls(float(np.sqrt(np.mean(diff * diff))), float(np.max(np.abs(diff))))


@dataclass(frozen=True)
class RpcFitReport:
    """Fit (cube) and validation errors of a fitted RPC against the model it was fitted to."""
    cube_points: int
    validation_points: int
    height_range: tuple
    cube_col: AxisErrors
    cube_row: AxisErrors
    validation_col: AxisErrors
    validation_row: AxisErrors
    #: image coordinates ("col", "row") fitted as plain cubic polynomials (denominator near zero)
    polynomial: tuple
    iterations: int

    @property
    def fallback(self):
        """True where a coordinate fell back to a cubic polynomial."""
        return bool(self.polynomial)

    @property
    def max_error(self):
        """Largest |error| (px) of either coordinate on the cube and the validation points."""
        return max(e.max for e in (self.cube_col, self.cube_row, self.validation_col, self.validation_row))

    def summary(self):
        """One line: points, RMS / max errors, fallback."""
        kind = (f"cubic polynomial for {' and '.join(self.polynomial)} (denominator near zero)"
                if self.polynomial else "rational 3/3")
        return (f"{kind}; cube {self.cube_points} points: col RMS {self.cube_col.rms:.2e} max "
                f"{self.cube_col.max:.2e} px, row RMS {self.cube_row.rms:.2e} max {self.cube_row.max:.2e} px; "
                f"validation {self.validation_points} points: col RMS {self.validation_col.rms:.2e} max "
                f"{self.validation_col.max:.2e} px, row RMS {self.validation_row.rms:.2e} max "
                f"{self.validation_row.max:.2e} px")


def _grid(lo, hi, n, validation):
    """n values from lo to hi, or for validation 2 (n - 1) values in the middles of a grid twice as
    dense."""
    if not validation:
        return np.linspace(lo, hi, n)
    k = 2 * (n - 1)
    return lo + (np.arange(k) + 0.5) * (hi - lo) / k


def _points(model, height_range, grid, validation):
    """Image points (col, row), heights and ground (lon, lat) of the cube or the validation grid."""
    cols, rows = model.size
    axes = [_grid(0.0, cols, grid[0], validation), _grid(0.0, rows, grid[1], validation),
            _grid(height_range[0], height_range[1], grid[2], validation)]
    col, row, h = (a.ravel() for a in np.meshgrid(*axes, indexing="ij"))
    try:
        lon, lat = model.image_to_ground(col, row, h)
    except GeometryError as exc:
        raise InputError(f"cannot fit an RPC: the sensor model has no ground position over the whole image and "
                         f"height range ({exc})") from exc
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    bad = ~(np.isfinite(lon) & np.isfinite(lat))
    if bad.any():
        i = np.flatnonzero(bad)[0]
        raise InputError(f"cannot fit an RPC: the sensor model gives no ground position for {bad.sum()} of "
                         f"{bad.size} image points, e.g. ({col[i]:.1f}, {row[i]:.1f}) at {h[i]:.1f} m; is its "
                         f"orientation complete for the whole image ({cols} x {rows} px) and the height range "
                         f"{height_range[0]:.0f} .. {height_range[1]:.0f} m plausible?")
    return col, row, h, lon, lat


def _mid_half(values):
    lo, hi = float(np.min(values)), float(np.max(values))
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def _solve(a, b, regularisation):
    """Tikhonov least squares: argmin |a x - b|^2 + lambda |x|^2, lambda = regularisation * trace(a'a) / m,
    by SVD of the augmented system."""
    m = a.shape[1]
    lam = regularisation * float(np.sum(a * a)) / m
    aug = np.vstack([a, math.sqrt(lam) * np.eye(m)])
    return np.linalg.lstsq(aug, np.concatenate([b, np.zeros(m)]), rcond=None)[0]


def _near_pole(den):
    """Whether a denominator (values over the domain) changes sign or comes near zero."""
    return bool(np.min(den) <= 0.0 or np.min(den) < MIN_DEN_RATIO * np.max(den)) or not np.all(np.isfinite(den))


def _fit_axis(t, v, t_check, regularisation):
    """(num, den, iterations) of v = num.t / den.t; den = (1, 0, ...) where the rational fit has a
    denominator near zero on t or t_check (then iterations = 0)."""
    a = np.hstack([t, -v[:, None] * t[:, 1:]])
    den = np.ones(v.size)
    for iteration in range(1, MAX_ITERATIONS + 1):
        x = _solve(a / den[:, None], v / den, regularisation)
        den_coef = np.concatenate([[1.0], x[NUM_TERMS:]])
        new = t @ den_coef
        if _near_pole(new) or _near_pole(t_check @ den_coef):
            break
        settled = np.max(np.abs(new - den)) < DEN_TOL
        den = new
        if settled:
            return x[:NUM_TERMS], den_coef, iteration
    else:
        return x[:NUM_TERMS], den_coef, MAX_ITERATIONS
    polynomial = np.zeros(NUM_TERMS)
    polynomial[0] = 1.0
    return _solve(t, v, regularisation), polynomial, 0


def fit_rpc(model, height_range, grid=DEFAULT_GRID, regularisation=DEFAULT_REGULARISATION, feedback=None):
    """(RpcModel, RpcFitReport): an RPC00B (degree 3/3) fitted to `model` over its whole image and
    `height_range` (min, max ellipsoidal heights, m) on a cube of grid = (columns, rows, heights)
    points (module docstring). RpcModel(coefficients, size=model.size) reproduces
    model.ground_to_image in GDAL's pixel convention."""
    lo, hi = (float(v) for v in height_range)
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        raise InputError(f"cannot fit an RPC over the height range {lo} .. {hi} m: give a finite range with "
                         "the highest height above the lowest (e.g. the terrain's range plus a margin)")
    grid = tuple(int(g) for g in grid)
    if len(grid) != 3 or min(grid) < 4:
        raise InputError(f"the RPC cube grid {grid} needs 3 sizes (columns, rows, heights) of at least 4 each: "
                         "a cubic needs 4 values per axis")
    if min(model.size) <= 0:
        raise InputError(f"cannot fit an RPC to an image of size {model.size}")
    progress.step(feedback, 0.0, f"RPC cube of {grid[0]} x {grid[1]} x {grid[2]} points, heights {lo:.0f} .. "
                                 f"{hi:.0f} m")
    col, row, h, lon, lat = _points(model, (lo, hi), grid, validation=False)
    vcol, vrow, vh, vlon, vlat = _points(model, (lo, hi), grid, validation=True)
    samp, line = col - 0.5, row - 0.5
    (long_off, long_scale), (lat_off, lat_scale), (h_off, h_scale), (samp_off, samp_scale), (line_off, line_scale) = (
        _mid_half(v) for v in (lon, lat, h, samp, line))
    if min(long_scale, lat_scale) <= 0.0:
        raise InputError("cannot fit an RPC: the sensor model maps the whole image to one ground point")

    def terms(x, y, z):
        return rpc_terms((x - long_off) / long_scale, (y - lat_off) / lat_scale, (z - h_off) / h_scale)

    t, t_check = terms(lon, lat, h), terms(vlon, vlat, vh)
    progress.step(feedback, 30.0)
    samp_num, samp_den, it_s = _fit_axis(t, (samp - samp_off) / samp_scale, t_check, regularisation)
    progress.step(feedback, 60.0)
    line_num, line_den, it_l = _fit_axis(t, (line - line_off) / line_scale, t_check, regularisation)
    coefficients = RpcCoefficients.from_fields({
        "LINE_NUM_COEFF": line_num, "LINE_DEN_COEFF": line_den, "SAMP_NUM_COEFF": samp_num,
        "SAMP_DEN_COEFF": samp_den, "LINE_OFF": line_off, "SAMP_OFF": samp_off, "LAT_OFF": lat_off,
        "LONG_OFF": long_off, "HEIGHT_OFF": h_off, "LINE_SCALE": line_scale, "SAMP_SCALE": samp_scale,
        "LAT_SCALE": lat_scale, "LONG_SCALE": long_scale, "HEIGHT_SCALE": h_scale}, "fitted RPC")
    rpc = RpcModel(coefficients, size=model.size, source="fitted RPC")
    progress.step(feedback, 90.0)
    fc, fr = rpc.ground_to_image(lon, lat, h)
    gc, gr = rpc.ground_to_image(vlon, vlat, vh)
    report = RpcFitReport(
        cube_points=col.size, validation_points=vcol.size, height_range=(lo, hi),
        cube_col=AxisErrors.of(fc - col), cube_row=AxisErrors.of(fr - row),
        validation_col=AxisErrors.of(gc - vcol), validation_row=AxisErrors.of(gr - vrow),
        polynomial=tuple(name for name, it in (("col", it_s), ("row", it_l)) if it == 0),
        iterations=max(it_s, it_l))
    progress.step(feedback, 100.0, report.summary())
    return rpc, report


def default_height_range(terrain_range):
    """(min, max) heights for the cube: the terrain height range widened by HEIGHT_MARGIN of its span,
    at least MIN_HEIGHT_MARGIN m, on either side."""
    lo, hi = (float(v) for v in terrain_range)
    margin = max(MIN_HEIGHT_MARGIN, HEIGHT_MARGIN * (hi - lo))
    return lo - margin, hi + margin


def rpc_txt_path(image_path, folder=None, name=None):
    """Where an image's fitted RPC goes: beside the raster as <stem>_RPC.TXT, GDAL's own naming, so
    GDAL reads it with the raster; or in `folder` as <name (default: the stem)>_RPC.TXT."""
    stem = os.path.splitext(os.path.basename(os.fspath(image_path)))[0]
    if folder is None:
        return os.path.join(os.path.dirname(os.path.abspath(image_path)), f"{stem}_RPC.TXT")
    return os.path.join(os.fspath(folder), f"{name or stem}_RPC.TXT")


def write_fitted_rpc(rpc, path, overwrite=False):
    """Write `rpc` as a _RPC.TXT (rpc_io.write_rpc_txt, atomic); an existing file, such as the RPC an
    image came with, is only replaced when `overwrite` is true."""
    path = os.fspath(path)
    if os.path.exists(path) and not overwrite:
        raise InputError(f"{path} exists already (the RPC the image came with, or an earlier fit); set the "
                         "overwrite option to replace it, or write the fitted RPCs to an output folder")
    rpc_io.write_rpc_txt(rpc, path)
    return path


def raster_reads(raster, rpc):
    """Whether GDAL, opening `raster`, finds the RPC of `rpc` (coefficients and offsets to 1e-12
    relative); a raster may carry other RPC that GDAL prefers, or none."""
    try:
        found = RpcCoefficients.from_fields(rpc_io.read_raster(raster).fields, os.fspath(raster))
    except PushbroomError:
        return False
    mine = rpc.coefficients
    return all(np.allclose(getattr(found, f.name), getattr(mine, f.name), rtol=1e-12, atol=0.0)
               for f in fields(mine))


def report_html(entries):
    """An HTML page with one table row per fitted image: `entries` are (name, path written, report)."""
    head = ("image", "RPC file", "kind", "heights (m)", "cube points", "cube RMS col / row (px)",
            "cube max col / row (px)", "validation points", "validation RMS col / row (px)",
            "validation max col / row (px)")
    rows = []
    for name, path, r in entries:
        kind = f"cubic polynomial for {', '.join(r.polynomial)}" if r.polynomial else "rational 3/3"
        cells = (name, path, kind, f"{r.height_range[0]:.0f} .. {r.height_range[1]:.0f}", r.cube_points,
                 f"{r.cube_col.rms:.2e} / {r.cube_row.rms:.2e}", f"{r.cube_col.max:.2e} / {r.cube_row.max:.2e}",
                 r.validation_points, f"{r.validation_col.rms:.2e} / {r.validation_row.rms:.2e}",
                 f"{r.validation_col.max:.2e} / {r.validation_row.max:.2e}")
        rows.append("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in cells) + "</tr>")
    return ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>RPC fit</title></head><body>\n"
            "<h1>RPC fit</h1>\n<p>Errors of the fitted RPC00B against the block's sensor model, in image "
            "pixels: on the cube it was fitted to, and on validation points (a grid twice as dense, shifted "
            "by half its step, over the same image and height range).</p>\n<table border=\"1\">\n<tr>"
            + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>\n" + "\n".join(rows)
            + "\n</table>\n</body></html>\n")
