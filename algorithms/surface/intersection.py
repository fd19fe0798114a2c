"""Forward intersection of object points from their image measurements in two or more images
(Kornus et al. 2006, section 3.5.1, eq. 5).

Per point a rigorous least-squares adjustment: unknowns the ground point, in local metres
(E, N, U) around the current estimate; observations the image coordinates (col, row) of its k rays
with weight 1 / sigma^2 (sigma in px); Gauss-Newton with the sensor models' partials
d(col, row)/d(lon, lat, h), converted to px/m by geodesy.metres_per_degree:

    A dx = l + v,  A = d(col, row)/d(E, N, U),  l = observed - computed,  dx = (A' P A)^-1 A' P l

K writes the same adjustment in object space, eq. 5: X = X0 + mu R32 R21 u1, three equations per
ray with unknowns X, Y, Z and one scale mu per ray (3k equations, 3 + k unknowns). Eliminating
mu leaves the two independent conditions of each ray, which are its image coordinates: the
unknowns (X, Y, Z), the redundancy 2k - 3 (1 for two rays, 3 for three) and, with the residuals
weighted as image measurements, the estimate are the same: this is the image-space form of eq. 5.

Start: the point closest in least squares to all its lines of sight (each through its ground points
at heights h0 -+ 500 m from `image_to_ground`). Per point the result carries the a priori covariance
(A' P A)^-1 in m^2 (E, N, U, from the given image sigma), the a posteriori sigma0 =
sqrt(v' P v / (2k - 3)) (unitless: about 1 when the image sigma is right; a posteriori sigmas =
sigma0 x a priori sigmas), the RMS of the 2k image residuals (px), the iterations and a status."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from .. import histogram, progress
from ..errors import InputError
from ..geodesy import ecef_to_geodetic, metres_per_degree, offset_enu
from ..progress import Feedback
from ..sigmas import IMAGE_SIGMA

STATUS_NAMES = (
    "converged",
    "not converged",
    "diverged",
    "outside a model's domain",
    "fewer than 2 rays",
    "singular geometry",
)
CONVERGED, NOT_CONVERGED, DIVERGED, OUTSIDE, TOO_FEW_RAYS, SINGULAR = range(len(STATUS_NAMES))

#: convergence: largest coordinate change (m) of the last step
TOLERANCE = 1e-4
#: a step longer than this (m) means the iteration runs away
MAX_STEP = 1e5
#: half the height difference (m) of the two ground points that define a line of sight for the start
START_HALF_HEIGHT = 500.0
#: det(N) / prod(diag(N)) (1 for independent unknowns, 0 for parallel rays) below which the rays are
#: taken as parallel
SINGULAR_RATIO = 1e-12
#: points per chunk (memory and progress)
CHUNK = 200_000


class Measurements(NamedTuple):
    """Image measurements of object points, one row per measurement: the image id, the point it belongs
    to (any integers), col, row (GDAL convention) and sigma (px, a number or one per measurement)."""

    image: ArrayLike
    point: ArrayLike
    col: ArrayLike
    row: ArrayLike
    sigma: ArrayLike = IMAGE_SIGMA


@dataclass
class Intersection:
    """Per point (sorted by `point`): the ground point and its precision (module docstring).
    Only points with status CONVERGED have coordinates and statistics; the others are NaN."""

    point: np.ndarray  # the point indices given, sorted, unique
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray  # ellipsoidal height, m
    rays: np.ndarray  # number of image measurements
    status: np.ndarray  # index into STATUS_NAMES
    iterations: np.ndarray
    sigma0: np.ndarray  # a posteriori standard deviation of unit weight
    rms: np.ndarray  # RMS of the image residuals, px
    covariance: np.ndarray  # (n, 3, 3) a priori covariance of (E, N, U), m^2

    def __len__(self):
        return len(self.point)

    @property
    def ok(self):
        return self.status == CONVERGED

    @property
    def sigma(self):
        """(n, 3) a priori standard deviations of E, N, U (m)."""
        return np.sqrt(np.diagonal(self.covariance, axis1=1, axis2=2))

    def status_counts(self):
        """{status name: count} of the statuses that occur."""
        counts = np.bincount(self.status, minlength=len(STATUS_NAMES))
        return {name: int(c) for name, c in zip(STATUS_NAMES, counts) if c}


def _inverse_symmetric(m):
    """Inverse and determinant of symmetric 3 x 3 matrices (n, 3, 3) by cofactors."""
    a00, a01, a02, a11, a12, a22 = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2], m[:, 1, 1], m[:, 1, 2], m[:, 2, 2]
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    inverse = np.stack([c00, c01, c02, c01, c11, c12, c02, c12, c22], axis=1).reshape(-1, 3, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        return inverse / det[:, None, None], det


def _start(models, image, col, row, point, go, h0):
    """ECEF starting points of the points `go` (sorted, each with a measurement; `point` sorted) and
    whether each is a true intersection: the point closest in least squares to the lines of sight of
    all their measurements (each through the two points of the model's `ray_points` at h0 -+
    START_HALF_HEIGHT; `closest_to_lines`). With fewer than two lines or parallel ones, the point
    at h0 of the first line (NaN if no ray meets the ground) and ok False."""
    if not go.size:
        return np.zeros((0, 3)), np.zeros(0, bool)
    sel = np.flatnonzero(np.isin(point, go))
    ends = np.full((2, sel.size, 3), np.nan)
    for key in np.unique(image[sel]):
        s = image[sel] == key
        ends[0, s], ends[1, s] = models[key].ray_points(col[sel][s], row[sel][s], h0, START_HALF_HEIGHT)
    starts = np.flatnonzero(np.r_[True, point[sel][1:] != point[sel][:-1]])
    xyz, ok = np.empty((starts.size, 3)), np.zeros(starts.size, np.bool_)
    closest_to_lines(ends[0], ends[1], np.r_[starts, sel.size], SINGULAR_RATIO, xyz, ok)
    return xyz, ok


@njit(cache=True, nogil=True)
def closest_to_lines(p0, p1, bounds, singular_ratio, xyz, ok):
    """Per group g (lines bounds[g]:bounds[g + 1], each through p0 and p1; lines with a NaN end are
    unusable): X = (sum_i A_i)^-1 sum_i A_i m_i, A_i = I - u_i u_i' (u_i unit direction, m_i the
    midpoint), the point closest in least squares to the lines (for two lines the midpoint of their
    common perpendicular), solved by cofactors; ok when at least two usable lines give det(sum A) >
    singular_ratio x the product of its diagonal, else the midpoint of the first usable line (NaN if
    none)."""
    n, b = np.empty((3, 3)), np.empty(3)
    u, m = np.empty(3), np.empty(3)
    for g in range(bounds.size - 1):
        n[:, :], b[:] = 0.0, 0.0
        usable, first = 0, -1
        for i in range(bounds[g], bounds[g + 1]):
            finite = True
            for r in range(3):
                u[r] = p1[i, r] - p0[i, r]
                m[r] = 0.5 * (p0[i, r] + p1[i, r])
                finite = finite and math.isfinite(u[r]) and math.isfinite(m[r])
            if not finite:
                continue
            usable += 1
            first = i if first < 0 else first
            norm = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
            for r in range(3):
                u[r] /= norm
            for r in range(3):
                for c in range(3):
                    a = (1.0 if r == c else 0.0) - u[r] * u[c]
                    n[r, c] += a
                    b[r] += a * m[c]
        c00 = n[1, 1] * n[2, 2] - n[1, 2] * n[2, 1]
        c01 = n[1, 2] * n[2, 0] - n[1, 0] * n[2, 2]
        c02 = n[1, 0] * n[2, 1] - n[1, 1] * n[2, 0]
        det = n[0, 0] * c00 + n[0, 1] * c01 + n[0, 2] * c02
        ok[g] = usable >= 2 and det > singular_ratio * n[0, 0] * n[1, 1] * n[2, 2]
        if ok[g]:  # N is symmetric: X = adj(N) b / det
            xyz[g, 0] = (c00 * b[0] + c01 * b[1] + c02 * b[2]) / det
            xyz[g, 1] = (
                c01 * b[0]
                + (n[0, 0] * n[2, 2] - n[0, 2] * n[2, 0]) * b[1]
                + (n[0, 1] * n[2, 0] - n[0, 0] * n[2, 1]) * b[2]
            ) / det
            xyz[g, 2] = (
                c02 * b[0]
                + (n[0, 1] * n[2, 0] - n[0, 0] * n[2, 1]) * b[1]
                + (n[0, 0] * n[1, 1] - n[0, 1] * n[1, 0]) * b[2]
            ) / det
        else:
            for r in range(3):
                xyz[g, r] = 0.5 * (p0[first, r] + p1[first, r]) if first >= 0 else np.nan


#: the arrays of Measurements, one row per measurement: image, point, col, row, sigma
_Rows = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _check_inputs(models: dict[Any, Any], measurements: Measurements) -> _Rows:
    """The measurements as contiguous 1-D arrays of one length (the sigma broadcast); InputError where they
    cannot be (lengths, an image without a model, non-finite coordinates, a sigma not positive)."""
    image, point, col, row, sigma = measurements
    try:
        arrays = np.broadcast_arrays(
            np.asarray(image).ravel(),
            np.asarray(point).ravel(),
            np.asarray(col, float).ravel(),
            np.asarray(row, float).ravel(),
            np.asarray(sigma, float).ravel(),
        )
    except ValueError as exc:
        raise InputError(f"image ids, point indices, col, row and sigma must have one length ({exc})") from None
    image, point, col, row, sigma = (np.ascontiguousarray(a) for a in arrays)
    missing = sorted({str(k) for k in np.unique(image)} - {str(k) for k in models})
    if missing:
        raise InputError(
            f"no sensor model for image(s) {', '.join(missing)}; models are given for "
            f"{', '.join(str(k) for k in models) or 'none'}"
        )
    if not (np.isfinite(col).all() and np.isfinite(row).all()):
        raise InputError("image coordinates must be finite numbers")
    if not (np.isfinite(sigma).all() and (sigma > 0).all()):
        raise InputError("the image sigma must be a positive number (px)")
    return image, point, col, row, sigma


def _default_height(models):
    """Mean of the height ranges of the models that have one (RPC), else 0 m."""
    ranges = [m.height_range for m in models.values() if hasattr(m, "height_range")]
    return float(np.mean(ranges)) if ranges else 0.0


def intersect(
    models: dict[Any, Any],
    measurements: Measurements,
    h0: float | None = None,
    max_iter: int = 10,
    tol: float = TOLERANCE,
    feedback: Feedback | None = None,
) -> Intersection:
    """Intersect the object points of image measurements (module docstring).

    `models`: dict image id -> sensor model with `partials`, `ground_to_image`, `image_to_ground`
    (SpotModel, RpcModel); `measurements`: Measurements (image ids, the points they belong to, col, row,
    sigma). `h0`: height (m) of the start (default: the models' mean height range, or 0 m). Returns an
    Intersection. Raises InputError on unusable input; points that cannot be intersected get a status
    (fewer than 2 rays, a measurement outside its image or a ray outside a model's domain, parallel rays,
    no convergence in `max_iter` steps of < `tol` m)."""
    image, point, col, row, sigma = _check_inputs(models, measurements)
    h0 = _default_height(models) if h0 is None else float(h0)
    ids, inverse = np.unique(point, return_inverse=True)
    order = np.lexsort((image, inverse))
    inverse, image, col, row, sigma = inverse[order], image[order], col[order], row[order], sigma[order]
    n = ids.size
    rays = np.bincount(inverse, minlength=n)
    fields = [
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full(n, NOT_CONVERGED, np.int8),
        np.zeros(n, np.int32),
        np.full(n, np.nan),
        np.full(n, np.nan),
        np.full((n, 3, 3), np.nan),
    ]
    chunks = np.arange(0, n + CHUNK, CHUNK).clip(max=n)
    bounds = np.searchsorted(inverse, chunks)
    for k in range(len(chunks) - 1):
        a, b, lo, hi = chunks[k], chunks[k + 1], bounds[k], bounds[k + 1]
        values = _intersect_chunk(
            models,
            (image[lo:hi], inverse[lo:hi] - a, col[lo:hi], row[lo:hi], sigma[lo:hi]),
            rays[a:b],
            h0,
            (max_iter, tol),
            progress.scaled(feedback, 100.0 * k / (len(chunks) - 1), 100.0 * (k + 1) / (len(chunks) - 1)),
        )
        for array, value in zip(fields, values):
            array[a:b] = value
    lon, lat, h, status, iterations, sigma0, rms, covariance = fields
    bad = status != CONVERGED
    for array in (lon, lat, h, sigma0, rms, covariance):
        array[bad] = np.nan
    return Intersection(ids, lon, lat, h, rays, status, iterations, sigma0, rms, covariance)


def intersect_measured(models: list[Any], cols: ArrayLike, rows: ArrayLike, h0: float | None = None) -> Intersection:
    """`intersect` of m points measured in each of k images: `models` a list of k models, `cols` and `rows`
    (k, m) arrays (row i: image i's positions); the points are 0 ... m - 1, the images 0 ... k - 1."""
    cols, rows = np.asarray(cols, float), np.asarray(rows, float)
    k, m = cols.shape
    return intersect(
        dict(enumerate(models)),
        Measurements(np.tile(np.arange(k), m), np.repeat(np.arange(m), k), cols.T.ravel(), rows.T.ravel()),
        h0=h0,
    )


def _initial_status(models, image, point, col, row, rays):
    """Per point: TOO_FEW_RAYS, OUTSIDE (a measurement outside its image) or NOT_CONVERGED (to go)."""
    status = np.where(rays < 2, TOO_FEW_RAYS, NOT_CONVERGED).astype(np.int8)
    for key in np.unique(image):
        sel = np.flatnonzero(image == key)
        cols, rows = models[key].size
        outside = sel[(col[sel] < 0) | (col[sel] > cols) | (row[sel] < 0) | (row[sel] > rows)]
        status[point[outside][rays[point[outside]] >= 2]] = OUTSIDE
    return status


def closest_points(
    models: dict[Any, Any],
    image_ids: ArrayLike,
    point_index: ArrayLike,
    col: ArrayLike,
    row: ArrayLike,
    h0: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The start of `intersect` alone, without its adjustment: per point the point closest in least
    squares to the lines of sight of its measurements (`_start`). Returns (the point indices given,
    sorted and unique; lon, lat, h; ok: at least two non-parallel lines inside the images)."""
    image, point, col, row, _ = _check_inputs(models, Measurements(image_ids, point_index, col, row, 1.0))
    h0 = _default_height(models) if h0 is None else float(h0)
    ids, inverse = np.unique(point, return_inverse=True)
    order = np.lexsort((image, inverse))
    inverse, image, col, row = inverse[order], image[order], col[order], row[order]
    status = _initial_status(models, image, inverse, col, row, np.bincount(inverse, minlength=ids.size))
    go = np.flatnonzero(status == NOT_CONVERGED)
    lon, lat, h = np.full(ids.size, np.nan), np.full(ids.size, np.nan), np.full(ids.size, np.nan)
    xyz, ok = _start(models, image, col, row, inverse, go, h0)
    lon[go], lat[go], h[go] = ecef_to_geodetic(xyz)
    good = np.zeros(ids.size, bool)
    good[go] = ok & np.isfinite(h[go])
    return ids, lon, lat, h, good


def _intersect_chunk(
    models: dict[Any, Any],
    measurements: _Rows,
    rays: np.ndarray,
    h0: float,
    convergence: tuple[int, float],
    feedback: Feedback | None,
) -> tuple[np.ndarray, ...]:
    """Intersect the points 0 .. len(rays) - 1 of one chunk from their `measurements` (the arrays of
    Measurements, sorted by point), in at most max_iter steps down to tol m (`convergence`). Returns lon,
    lat, h, status, iterations, sigma0, rms, covariance."""
    image, point, col, row, sigma = measurements
    max_iter, tol = convergence
    n = rays.size
    status = _initial_status(models, image, point, col, row, rays)
    lon, lat, h = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    iterations, sigma0, rms = np.zeros(n, np.int32), np.full(n, np.nan), np.full(n, np.nan)
    covariance = np.full((n, 3, 3), np.nan)
    go = np.flatnonzero(status == NOT_CONVERGED)
    lon[go], lat[go], h[go] = ecef_to_geodetic(_start(models, image, col, row, point, go, h0)[0])
    status[go[~np.isfinite(h[go])]] = OUTSIDE
    observed = np.column_stack([col, row])
    weight = 1.0 / sigma**2
    for iteration in range(1, max_iter + 1):
        progress.step(feedback, 100.0 * (iteration - 1) / max_iter)
        sel = np.flatnonzero(status[point] == NOT_CONVERGED)
        if not sel.size:
            break
        p = point[sel]
        starts = np.flatnonzero(np.r_[True, p[1:] != p[:-1]])
        q, owner = p[starts], np.cumsum(np.r_[False, p[1:] != p[:-1]])
        computed = np.empty((sel.size, 2))
        jac = np.empty((sel.size, 2, 3))
        for key in np.unique(image[sel]):
            s = image[sel] == key
            d = models[key].partials(lon[p[s]], lat[p[s]], h[p[s]])
            c, r, d = d["col"], d["row"], d["d_ground"]
            computed[s, 0], computed[s, 1], jac[s] = c, r, d
        scale = np.column_stack([*metres_per_degree(lat[q], h[q]), np.ones(q.size)])  # m per (deg, deg, m)
        jac /= scale[owner][:, None, :]
        misclosure = observed[sel] - computed
        weighted = jac * weight[sel][:, None, None]
        normal = np.add.reduceat(np.einsum("kji,kjl->kil", weighted, jac), starts)
        rhs = np.add.reduceat(np.einsum("kji,kj->ki", weighted, misclosure), starts)
        finite = np.isfinite(normal).all(axis=(1, 2)) & np.isfinite(rhs).all(axis=1)
        status[q[~finite]] = OUTSIDE
        normal[~finite], rhs[~finite] = np.eye(3), 0.0
        inverse, det = _inverse_symmetric(normal)
        singular = finite & ~(det > SINGULAR_RATIO * np.prod(np.diagonal(normal, axis1=1, axis2=2), axis=1))
        status[q[singular]] = SINGULAR
        inverse[singular] = 0.0
        dx = np.einsum("kij,kj->ki", inverse, rhs)
        lon[q], lat[q], h[q] = offset_enu(lon[q], lat[q], h[q], dx)
        # statistics of this linearisation: post-fit residuals v = A dx - l
        v = np.einsum("kij,kj->ki", jac, dx[owner]) - misclosure
        sigma0[q] = np.sqrt(np.add.reduceat(weight[sel] * (v * v).sum(1), starts) / (2 * rays[q] - 3))
        rms[q] = np.sqrt(np.add.reduceat((v * v).sum(1), starts) / (2 * rays[q]))
        covariance[q] = inverse
        iterations[q] = iteration
        step = np.abs(dx).max(axis=1)
        live = status[q] == NOT_CONVERGED
        status[q[live & ~(step <= MAX_STEP)]] = DIVERGED
        status[q[live & (step < tol)]] = CONVERGED
    _check_height_domain(models, image, point, h, status)
    return lon, lat, h, status, iterations, sigma0, rms, covariance


def _check_height_domain(models, image, point, h, status):
    """RPC models hold within their height range: a point beyond it by more than half its width is
    outside the model's domain."""
    for key in np.unique(image):
        limits = getattr(models[key], "height_range", None)
        if limits is None:
            continue
        lo, hi = limits
        p = point[image == key]
        beyond = (status[p] == CONVERGED) & ((h[p] < lo - 0.5 * (hi - lo)) | (h[p] > hi + 0.5 * (hi - lo)))
        status[p[beyond]] = OUTSIDE


#: the summary's medians come from sparse histograms of log10(value) in bins of SUMMARY_BIN decades
#: over SUMMARY_DECADES (values beyond fall in the end bins), so that the summaries of the parts of a
#: tiled run add up: a median comes from the geometric centres of its bins, within 0.012 % of the exact median
SUMMARY_BIN = 1e-4
SUMMARY_DECADES = (-6.0, 6.0)
_SUMMARY_LAST = int(round((SUMMARY_DECADES[1] - SUMMARY_DECADES[0]) / SUMMARY_BIN)) - 1


class Summary:
    """Per point group: points, converged, and the medians of the a priori sigma_E, sigma_N, sigma_H (m)
    and of sigma0 of the converged ones; `add` takes the Intersection of a part, `merge` another
    part's Summary (both in any order: the sums are the same)."""

    def __init__(self):
        self.groups = {}  # group -> [points, converged, 4 sparse histograms (bins, counts)]

    def _group(self, g):
        return self.groups.setdefault(int(g), [0, 0, [histogram.EMPTY] * 4])

    def add(self, result, group=None):
        """Count the points of `result` (Intersection) with `group` (one per point; None: all group 0)."""
        group = np.zeros(len(result), int) if group is None else np.asarray(group)
        values = np.column_stack([result.sigma, result.sigma0])
        for g in np.unique(group):
            sel = group == g
            ok = sel & result.ok
            entry = self._group(g)
            entry[0] += int(sel.sum())
            entry[1] += int(ok.sum())
            with np.errstate(divide="ignore", invalid="ignore"):
                bins = np.floor((np.log10(values[ok]) - SUMMARY_DECADES[0]) / SUMMARY_BIN)
            finite = np.isfinite(values[ok])  # a NaN sigma is no value; 0 and inf go to the end bins
            bins = np.nan_to_num(bins, nan=0.0, neginf=0.0, posinf=_SUMMARY_LAST).clip(0, _SUMMARY_LAST)
            for q in range(4):
                entry[2][q] = histogram.add(entry[2][q], histogram.count(bins[finite[:, q], q]))
        return self

    def merge(self, other):
        """Add the counts of the Summary `other`; returns self."""
        for g, (points, converged, hists) in other.groups.items():
            entry = self._group(g)
            entry[0] += points
            entry[1] += converged
            entry[2] = [histogram.add(mine, theirs) for mine, theirs in zip(entry[2], hists)]
        return self

    def rows(self):
        """One dict per group, ascending: group, points, converged, sigma_e, sigma_n, sigma_h, sigma0."""
        rows = []
        for g in sorted(self.groups):
            points, converged, hists = self.groups[g]
            medians = [_histogram_median(*h) for h in hists]
            rows.append(
                {
                    "group": g,
                    "points": points,
                    "converged": converged,
                    "sigma_e": medians[0],
                    "sigma_n": medians[1],
                    "sigma_h": medians[2],
                    "sigma0": medians[3],
                }
            )
        return rows


def _histogram_median(bins, counts):
    """The median of a sparse Summary histogram, of the geometric centres of its bins; NaN when empty."""
    return histogram.median(10.0 ** (SUMMARY_DECADES[0] + (bins + 0.5) * SUMMARY_BIN), counts)


def summary_rows(result, group=None):
    """The Summary rows of one Intersection `result` with `group` (one per point; None: all group 0)."""
    return Summary().add(result, group).rows()


def format_summary(rows):
    """The summary rows as a text table."""
    lines = [f"{'group':>5} {'points':>9} {'converged':>9} {'sigma_E':>8} {'sigma_N':>8} {'sigma_H':>8} {'sigma0':>7}"]
    lines += [
        f"{r['group']:>5} {r['points']:>9} {r['converged']:>9} {r['sigma_e']:>8.3f} {r['sigma_n']:>8.3f} "
        f"{r['sigma_h']:>8.3f} {r['sigma0']:>7.3f}"
        for r in rows
    ]
    return "\n".join(lines)


@dataclass(frozen=True)
class HeightDifferences:
    """RPC minus rigorous object points (m, local east / north / up) of the points both intersect."""

    point: np.ndarray
    de: np.ndarray
    dn: np.ndarray
    dh: np.ndarray
    #: points that one of the two model sets could not intersect
    missing: int

    def summary(self):
        """One line: count, dh mean / RMS / max |dh|, RMS of dE and dN (m)."""
        if not self.point.size:
            return f"no point intersected by both the rigorous models and the RPCs ({self.missing} tried)"
        rms = {k: float(np.sqrt(np.mean(getattr(self, k) ** 2))) for k in ("de", "dn", "dh")}
        return (
            f"{self.point.size} points ({self.missing} not intersected by both): dh mean {np.mean(self.dh):.4f} m, "
            f"RMS {rms['dh']:.4f} m, max |dh| {np.max(np.abs(self.dh)):.4f} m; RMS dE {rms['de']:.4f} m, "
            f"dN {rms['dn']:.4f} m"
        )


def height_differences(
    models_rigorous: dict[Any, Any],
    models_rpc: dict[Any, Any],
    image_ids: ArrayLike,
    point_index: ArrayLike,
    col: ArrayLike,
    row: ArrayLike,
    h0: float | None = None,
) -> HeightDifferences:
    """Kornus et al. 2006, section 3.5.2, Table 5: the object points of image measurements (one row per
    measurement: image id, point index, col, row) intersected once with the rigorous models
    and once with their RPCs (dicts image id -> model with the same ids), and the differences."""
    if set(models_rigorous) != set(models_rpc):
        raise InputError(
            f"the rigorous models (images {sorted(models_rigorous)}) and the RPCs (images "
            f"{sorted(models_rpc)}) must describe the same images"
        )
    measured = Measurements(image_ids, point_index, col, row)
    a = intersect(models_rigorous, measured, h0=h0)
    b = intersect(models_rpc, measured, h0=h0)
    ok = a.ok & b.ok
    east, north = metres_per_degree(a.lat[ok])
    return HeightDifferences(
        a.point[ok],
        (b.lon - a.lon)[ok] * east,
        (b.lat - a.lat)[ok] * north,
        (b.h - a.h)[ok],
        int(np.count_nonzero(~ok)),
    )
