"""Multi-photo geometrically constrained least-squares matching, MPGC (Gruen 1985; Baltsavias 1991),
the final refinement of Zhang and Gruen (2004).

A template of the reference image (0) centred at (x0, y0) is matched into n >= 1 search images at
once. Per search image i the grey-level model of LSM (lsm.py), f(k, l) = r0_i + r1_i g_i(x_i + a1_i k
+ a2_i l, y_i + a4_i k + a5_i l), Keys-cubic resampling. Unknowns: the object point X (dE, dN, dU in
metres from a linearisation point) and 8 per search image (shifts, 4 shape, 2 radiometric).

Geometric constraint, Baltsavias' formulation (a): the shifts stay free and the sensor models enter
as observations of weight 1 / sigma_geometry^2, x_i - f_i(X) = v (2 per search image) and x0 - f_0(X)
= v (the reference ray), linearised with J_i = d(col, row)/d(E, N, U). A small sigma_geometry
approaches the hard constraint x_i = f_i(X); a larger one tolerates orientation errors. The
linearisation point follows the estimate until the projections agree to LINEARISATION_TOLERANCE px.

Weights of image i's grey-level equations: 1 / (s^2 (1 + rep_i)) (rep_i = 1 / |det A_i| where image i
is coarser, as in lsm.py), times Tukey's biweight (1 - (v / (c s_i))^2)^2, c = TUKEY_C (params.py), against image
i's weighted residual RMS s_i of the previous iteration: plain least squares first, REWEIGHTINGS
re-weighted iterations, then fixed weights (docs/validation.md#mpgc-spot-triplet). s^2 is re-estimated
every iteration; sigma0 = s (DN). Optional support weights (Yoon and Kweon 2006) multiply them per
template sample: exp(-(k^2 + l^2) / (2 centre_sigma^2)) exp(-(m(k, l) - m(0, 0))^2 / (2 (similarity
s_f)^2)), m the mean over SUPPORT_BOX^2 samples (mpgc_kernels.py), s_f the template's standard deviation (a factor is 1
where its parameter is 0); off by default (docs/validation.md#mpgc-support-weights).

Precision: the n equations of a template sample share its noise, covariance s^2 (1 1' + diag(r1_i^2
rep_i)); the unknowns' covariance is the sandwich N^-1 (A'P C P A) N^-1. From it: error ellipses of
the search positions (px) and sigmas of E, N, U (m). Geometric test t = v'Pv / r over the 2 (n + 1)
geometric observations (r their redundancy), about 1 for a consistent match, large when the rays do
not meet (a wrong match or orientation); support weights make it smaller (docs/validation.md#mpgc-precision).

Reliability in [0, 1]: 0 where the match failed or moved more than max_shift px; else min_i rho_i *
min(1, max_ellipse / largest semi-major axis) * min(1, max_geo_test / t). Failed points keep their
approximate values with reliability 0."""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geodesy import metres_per_degree, offset_enu
from ..progress import step as progress_step
from .imagery import as_image
from .lsm import NOT_CONVERGED, OK, OUTSIDE, SINGULAR
from .mpgc_kernels import COV, GEO_RED, GEO_RMS, GEO_VTPV, NPI, SIGMA0, Solve, Stack, mpgc_batch, out_size
from .params import LsmParams

#: status codes: lsm.py's and a point a sensor model cannot project
NO_GEOMETRY = 4
STATUS_NAMES = ("ok", "window outside an image", "singular (flat texture)", "not converged", "no geometry")
#: px: largest disagreement between a model's projection of the estimate and its linearisation
LINEARISATION_TOLERANCE = 1e-3
#: re-linearisations of the sensor models (the first included)
PASSES = 3

__all__ = [
    "MpgcParams",
    "mpgc_dtype",
    "geometry",
    "initial_state",
    "match_points",
    "accepted",
    "STATUS_NAMES",
    "OK",
    "OUTSIDE",
    "SINGULAR",
    "NOT_CONVERGED",
    "NO_GEOMETRY",
]


@dataclass
class MpgcParams(LsmParams):
    """LSM's window and acceptance criteria plus the geometric constraint."""

    sigma_geometry: float = 0.2  # px: a priori sigma of the geometric observations (orientation)
    max_geo_test: float = 4.0  # geometric test t above which a point is rejected (chi^2_3 / 3 > 4: 0.7 %)
    tile: int = 512  # px of the reference image per tile of windows read at once
    centre_sigma: float = 0.0  # px: the support weights' Gaussian of the distance from the centre (0 = off)
    similarity: float = 0.0  # the support weights' grey-level scale, times the template's std (0 = off)

    def check(self):
        super().check()
        if not self.sigma_geometry >= 1e-4:
            raise InputError(f"sigma_geometry must be at least 1e-4 px, got {self.sigma_geometry}")
        if not self.max_geo_test > 0 or self.tile < 4 * self.template:
            raise InputError("max_geo_test must be positive and the tile at least 4 templates wide")
        if not (self.centre_sigma >= 0 and self.similarity >= 0):
            raise InputError(
                f"the support weights' centre_sigma and similarity must be 0 (off) or positive, got "
                f"{self.centre_sigma} and {self.similarity}"
            )
        return self


def mpgc_dtype(n):
    """Record layout for n search images: template centre (x0, y0); matched positions x, y (n);
    object point lon, lat (deg), h (m, ellipsoidal) and its sigma (E, N, U; m); per search image
    rho, error-ellipse semi-axes (px), final affine (a1, a2, a4, a5) and radiometry (r0, r1);
    sigma0 (DN), geometric residual RMS (px), test t and redundancy; shift (px, largest move from
    the approximation), iterations, status, reliability (module docstring)."""
    return np.dtype(
        [
            ("x0", "f8"),
            ("y0", "f8"),
            ("x", "f8", (n,)),
            ("y", "f8", (n,)),
            ("lon", "f8"),
            ("lat", "f8"),
            ("h", "f8"),
            ("sigma", "f4", (3,)),
            ("rho", "f4", (n,)),
            ("semi_major", "f4", (n,)),
            ("semi_minor", "f4", (n,)),
            ("affine", "f4", (n, 4)),
            ("radiometry", "f4", (n, 2)),
            ("sigma0", "f4"),
            ("geo_rms", "f4"),
            ("geo_test", "f4"),
            ("geo_redundancy", "f4"),
            ("shift", "f4"),
            ("iterations", "i2"),
            ("status", "i1"),
            ("reliability", "f4"),
        ]
    )


def geometry(models, lon, lat, h):
    """Projections cen (m, k, 2) and partials jac (m, k, 2, 3) = d(col, row)/d(E, N, U) in px/m
    of object points in the k images of `models` (metres from geodesy.metres_per_degree, the
    scale geodesy.offset_enu moves points by)."""
    m, k = lon.size, len(models)
    cen = np.empty((m, k, 2))
    jac = np.empty((m, k, 2, 3))
    if m == 0:
        return cen, jac
    me, mn = metres_per_degree(lat, h)
    for i, model in enumerate(models):
        part = model.partials(lon, lat, h)
        cen[:, i, 0] = part["col"]
        cen[:, i, 1] = part["row"]
        jac[:, i] = np.asarray(part["d_ground"]).reshape(m, 2, 3)
    jac[..., 0] /= me[:, None, None]
    jac[..., 1] /= mn[:, None, None]
    return cen, jac


def initial_state(cen, jac):
    """Per point and search image (x, a1, a2, y, a4, a5, r0, r1): the projection, the affine of a
    horizontal plane, A_i = J_i[EN] J_0[EN]^-1 (reference px -> image-i px), r0 = 0, r1 = 1."""
    m, k = cen.shape[:2]
    state = np.zeros((m, k - 1, NPI))
    j = jac[:, 0, :, :2]
    with np.errstate(all="ignore"):
        det = j[:, 0, 0] * j[:, 1, 1] - j[:, 0, 1] * j[:, 1, 0]
        inv0 = (
            np.stack([j[:, 1, 1], -j[:, 0, 1], -j[:, 1, 0], j[:, 0, 0]], axis=1).reshape(-1, 1, 2, 2)
            / det[:, None, None, None]
        )
        aff = jac[:, 1:, :, :2] @ inv0
    state[..., 0] = cen[:, 1:, 0]
    state[..., 3] = cen[:, 1:, 1]
    state[..., 1], state[..., 2] = aff[..., 0, 0], aff[..., 0, 1]
    state[..., 4], state[..., 5] = aff[..., 1, 0], aff[..., 1, 1]
    state[..., 7] = 1.0
    return state


def _points(x0, y0, lon, lat, h):
    try:
        arrays = np.broadcast_arrays(
            *(np.atleast_1d(np.asarray(v, dtype=np.float64)).ravel() for v in (x0, y0, lon, lat, h))
        )
    except ValueError as exc:
        raise InputError(f"x0, y0, lon, lat, h must have one length ({exc})") from None
    x0, y0, lon, lat, h = (np.ascontiguousarray(a) for a in arrays)
    if not (np.isfinite(x0).all() and np.isfinite(y0).all()):
        raise InputError("the template centres x0, y0 must be finite numbers")
    return x0, y0, lon, lat, h


def match_points(
    reference, searches, models, x0, y0, ground: tuple[np.ndarray, np.ndarray, np.ndarray], params=None, feedback=None
):
    """MPGC of template centres (x0, y0) of `reference` into the `searches` images, from the
    approximate object points `ground` (lon, lat, h) (module docstring).

    reference, searches: Image, Smoothed, raster path or 2-D array (resolution adaptation, e.g.
    resolution.adapt_resolution, is the caller's); models: the n + 1 sensor models (reference
    first) with `partials`; params: MpgcParams. Points are processed in tiles of the reference
    image (windows read once per tile, the kernel parallel over points). Returns mpgc_dtype(n)
    records in the order given; raises InputError on unusable input, CancelledError when
    cancelled."""
    lon, lat, h = ground
    params = (params or MpgcParams()).check()
    searches = list(searches)
    models = list(models)
    if not searches:
        raise InputError("MPGC needs at least one search image")
    if len(models) != len(searches) + 1:
        raise InputError(
            f"give one sensor model per image, the reference first: {len(searches) + 1} expected, {len(models)} given"
        )
    images = [as_image(reference)] + [as_image(s) for s in searches]
    x0, y0, lon, lat, h = _points(x0, y0, lon, lat, h)
    n = len(searches)
    records = np.zeros(x0.size, mpgc_dtype(n))
    tile = int(params.tile)
    key = np.floor(y0 / tile) * (images[0].size[0] // tile + 2) + np.floor(x0 / tile)
    groups = np.unique(key)
    for done, k in enumerate(groups):
        progress_step(feedback, 100.0 * done / len(groups))
        idx = np.flatnonzero(key == k)
        records[idx] = _match_tile(images, models, x0[idx], y0[idx], lon[idx], lat[idx], h[idx], params)
    progress_step(feedback, 100.0)
    return records


def _read(image, xlo, ylo, xhi, yhi):
    data, xa, ya = image.read(
        int(np.floor(xlo)),
        int(np.floor(ylo)),
        int(np.ceil(xhi - np.floor(xlo))) + 1,
        int(np.ceil(yhi - np.floor(ylo))) + 1,
    )
    return np.ascontiguousarray(data, dtype=np.float32), float(xa), float(ya)


def _windows(images, x0, y0, state, good, half, params):
    """Packed windows (buf, meta, offs) of the tile: the templates' box in the reference, the
    approximate search positions plus the templates' footprint and max_shift in each search image."""
    parts, offs = [], np.zeros((len(images), 2))
    pad = half + 3
    for i, image in enumerate(images):
        if not good.any():
            data, xa, ya = np.zeros((0, 0), np.float32), 0.0, 0.0
        elif i == 0:
            data, xa, ya = _read(
                image, x0[good].min() - pad, y0[good].min() - pad, x0[good].max() + pad, y0[good].max() + pad
            )
        else:
            s = state[good, i - 1]
            reach = pad * np.abs(s[:, [1, 2, 4, 5]]).max() + params.max_shift + 3.0
            data, xa, ya = _read(
                image, s[:, 0].min() - reach, s[:, 3].min() - reach, s[:, 0].max() + reach, s[:, 3].max() + reach
            )
        parts.append(data)
        offs[i] = xa, ya
    meta = np.zeros((len(images), 3), np.int64)
    meta[:, 1:] = [p.shape for p in parts]
    meta[1:, 0] = np.cumsum([p.size for p in parts])[:-1]
    return np.concatenate([p.ravel() for p in parts]), meta, offs


def _match_tile(images, models, x0, y0, lon, lat, h, params):
    n = len(images) - 1
    m = x0.size
    half = params.template // 2
    cen, jac = geometry(models, lon, lat, h)
    state = initial_state(cen, jac)
    good = (
        np.isfinite(cen).all(axis=(1, 2))
        & np.isfinite(jac).all(axis=(1, 2, 3))
        & np.isfinite(state).all(axis=(1, 2))
        & np.isfinite(lon)
        & np.isfinite(lat)
        & np.isfinite(h)
    )
    start = state.copy()
    buf, meta, offs = _windows(images, x0, y0, state, good, half, params)
    solve = Solve(
        half, params.max_iterations, params.convergence, params.sigma_geometry, params.centre_sigma, params.similarity
    )
    dx = np.zeros((m, 3))
    out = np.full((m, out_size(n)), np.nan)
    status = np.where(good, NOT_CONVERGED, NO_GEOMETRY).astype(np.int8)
    iterations = np.zeros(m, np.int64)
    base = [lon.copy(), lat.copy(), h.copy()]
    active = good.copy()
    for _ in range(PASSES):
        mpgc_batch(Stack(buf, meta, offs), x0, y0, cen, jac, state, dx, active, solve, out, status, iterations)
        moved = np.flatnonzero(active & (status == OK))
        point = offset_enu(base[0][moved], base[1][moved], base[2][moved], dx[moved])
        cen_new, jac_new = geometry(models, *point)
        lin_error = np.abs(cen_new - (cen[moved] + np.einsum("pkcj,pj->pkc", jac[moved], dx[moved])))
        with np.errstate(invalid="ignore"):
            lin_error = lin_error.max(axis=(1, 2)) if moved.size else np.zeros(0)
        for b, v in zip(base, point):
            b[moved] = v
        cen[moved], jac[moved], dx[moved] = cen_new, jac_new, 0.0
        status[moved[~np.isfinite(lin_error)]] = NO_GEOMETRY
        active[:] = False
        active[moved[lin_error > LINEARISATION_TOLERANCE]] = True
        if not active.any():
            break
    status[active] = NOT_CONVERGED  # the linearisation still moved after the last pass
    return _records(x0, y0, (lon, lat, h), start, state, base, (out, status, iterations), params)


def _records(x0, y0, ground, start, state, base, solved, params):
    """The records of the points at (x0, y0) from the approximate object points `ground` (lon, lat, h), the
    initial and final states (points, images, 8), the last object points `base` and the kernel's `solved` (out,
    status, iterations)."""
    lon, lat, h = ground
    out, status, iterations = solved
    n = state.shape[1]
    rec = np.zeros(x0.size, mpgc_dtype(n))
    ok = status == OK
    final = np.where(ok[:, None, None], state, start)
    rec["x0"], rec["y0"] = x0, y0
    rec["x"], rec["y"] = final[..., 0], final[..., 3]
    rec["affine"] = final[..., [1, 2, 4, 5]]
    rec["radiometry"] = final[..., 6:8]
    rec["lon"] = np.where(ok, base[0], lon)
    rec["lat"] = np.where(ok, base[1], lat)
    rec["h"] = np.where(ok, base[2], h)
    rec["status"] = status
    rec["iterations"] = np.minimum(iterations, np.iinfo(np.int16).max)
    q = np.where(ok[:, None], out, np.nan)
    rec["rho"] = q[:, 0 : 3 * n : 3]
    rec["semi_major"] = q[:, 1 : 3 * n : 3]
    rec["semi_minor"] = q[:, 2 : 3 * n : 3]
    t = 3 * n
    with np.errstate(invalid="ignore", divide="ignore"):
        rec["sigma"] = np.sqrt(q[:, [t + COV, t + COV + 3, t + COV + 5]])
        rec["sigma0"] = q[:, t + SIGMA0]
        rec["geo_rms"] = q[:, t + GEO_RMS]
        red = q[:, t + GEO_RED]
        rec["geo_redundancy"] = red
        rec["geo_test"] = np.where(red > 1e-6, q[:, t + GEO_VTPV] / np.where(red > 1e-6, red, 1.0), np.nan)
        rec["shift"] = np.where(
            ok, np.hypot(final[..., 0] - start[..., 0], final[..., 3] - start[..., 3]).max(axis=1), np.nan
        )
        rel = (
            np.clip(q[:, 0:t:3].min(axis=1), 0.0, 1.0)
            * np.minimum(1.0, params.max_ellipse / q[:, 1:t:3].max(axis=1))
            * np.minimum(1.0, params.max_geo_test / rec["geo_test"])
        )
        rec["reliability"] = np.where(ok & (rec["shift"] <= params.max_shift) & np.isfinite(rel), rel, 0.0)
    return rec


def accepted(records, params=None):
    """Points meeting the acceptance criteria: status OK, every rho > rho_min, every semi-major
    axis < max_ellipse, shift < max_shift, geometric test < max_geo_test."""
    params = params or MpgcParams()
    r = records
    with np.errstate(invalid="ignore"):
        return (
            (r["status"] == OK)
            & (r["rho"] > params.rho_min).all(axis=1)
            & (r["semi_major"] < params.max_ellipse).all(axis=1)
            & (r["shift"] < params.max_shift)
            & (r["geo_test"] < params.max_geo_test)
        )
