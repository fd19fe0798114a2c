"""numba kernels of the rigorous SPOT model (spot.SpotModel builds their packed inputs).

Packed inputs (the kernels over arrays take them as one PackedModel):
    eph    (n, 8)     Lagrange window, rows [t, w, X, Y, Z, VX, VY, VZ]; w_j = 1 / prod_k!=j (t_j - t_k)
    att_t  (m,)       attitude sample times; att_v (m, 3) yaw, pitch, roll (rad), linear in time,
                      held constant outside the samples
    look   (ncols, 2) psi_x, psi_y of detector k, whose centre is column k + 0.5 (GDAL convention)
    prm    (5,)       t_c, r_c, line period T, correction time scale, correction centre column p_c
    corr   (8, 4)     correction polynomials, rows X, Y, Z (m), yaw, pitch, roll, psi_x, psi_y (rad),
                      column j = coefficient of degree j (Corrections in spot_orientation.py)

Line time t = t_c + (row - r_c) T; corrections are evaluated at tau = (t - t_c) / time_scale and
q = (col - p_c) / 1000. Ground point X = P + mu R32 R21 u1 (spot_frames).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..dem import bilinear_scalar
from ..geodesy import E2, A, B, bowring, ecef_to_geodetic_scalar, geodetic_to_ecef_scalar
from .spot_frames import (
    Rotation,
    Vector,
    attitude_rotation,
    look_angles,
    look_vector,
    mat_mul,
    mat_t_vec,
    mat_vec,
    orbital_rotation,
)

NAN = math.nan


class PackedModel(NamedTuple):
    """The packed inputs of one model (module docstring): one argument of the kernels over arrays, which
    numba compiles as a tuple of arrays. spot.SpotModel builds it at each call, with the current corrections."""

    eph: np.ndarray
    att_t: np.ndarray
    att_v: np.ndarray
    look: np.ndarray
    prm: np.ndarray
    corr: np.ndarray


@njit(cache=True, nogil=True, error_model="numpy")
def lagrange(eph: np.ndarray, t: float) -> tuple[float, float, float, float, float, float]:
    """Position and velocity at t: Lagrange polynomial through the window's samples (barycentric form
    sum_j w_j/(t - t_j) y_j / sum_j w_j/(t - t_j)); NaNs outside the window (the orbit is never
    extrapolated, so image points far beyond the scene give NaN, not a made-up position)."""
    if not eph[0, 0] <= t <= eph[eph.shape[0] - 1, 0]:
        return NAN, NAN, NAN, NAN, NAN, NAN
    den = px = py = pz = vx = vy = vz = 0.0
    for j in range(eph.shape[0]):
        d = t - eph[j, 0]
        if d == 0.0:
            return eph[j, 2], eph[j, 3], eph[j, 4], eph[j, 5], eph[j, 6], eph[j, 7]
        c = eph[j, 1] / d
        den += c
        px += c * eph[j, 2]
        py += c * eph[j, 3]
        pz += c * eph[j, 4]
        vx += c * eph[j, 5]
        vy += c * eph[j, 6]
        vz += c * eph[j, 7]
    return px / den, py / den, pz / den, vx / den, vy / den, vz / den


@njit(cache=True, nogil=True, error_model="numpy")
def poly3(corr: np.ndarray, i: int, x: float) -> float:
    """sum_j corr[i, j] x^j."""
    return ((corr[i, 3] * x + corr[i, 2]) * x + corr[i, 1]) * x + corr[i, 0]


@njit(cache=True, nogil=True, error_model="numpy")
def poly3_slope(corr: np.ndarray, i: int, x: float) -> float:
    """d/dx of poly3(corr, i, x)."""
    return (3.0 * corr[i, 3] * x + 2.0 * corr[i, 2]) * x + corr[i, 1]


@njit(cache=True, nogil=True, error_model="numpy")
def attitude(att_t: np.ndarray, att_v: np.ndarray, t: float) -> Vector:
    """Yaw, pitch, roll at t: linear between samples, constant outside."""
    m = att_t.size
    if m == 1 or t <= att_t[0]:
        return att_v[0, 0], att_v[0, 1], att_v[0, 2]
    if t >= att_t[m - 1]:
        return att_v[m - 1, 0], att_v[m - 1, 1], att_v[m - 1, 2]
    k = np.searchsorted(att_t, t) - 1
    f = (t - att_t[k]) / (att_t[k + 1] - att_t[k])
    return (
        att_v[k, 0] + f * (att_v[k + 1, 0] - att_v[k, 0]),
        att_v[k, 1] + f * (att_v[k + 1, 1] - att_v[k, 1]),
        att_v[k, 2] + f * (att_v[k + 1, 2] - att_v[k, 2]),
    )


@njit(cache=True, nogil=True, error_model="numpy")
def corrected_state(
    eph: np.ndarray, att_t: np.ndarray, att_v: np.ndarray, prm: np.ndarray, corr: np.ndarray, t: float
) -> tuple[float, float, float, float, float, float, float, float, float, float]:
    """Corrected position P + dP, velocity V + d(dP)/dt and attitude angles (yaw, pitch, roll) at
    time t, and the correction time tau: a 10-tuple."""
    px, py, pz, vx, vy, vz = lagrange(eph, t)
    tau = (t - prm[0]) / prm[3]
    px += poly3(corr, 0, tau)
    py += poly3(corr, 1, tau)
    pz += poly3(corr, 2, tau)
    vx += poly3_slope(corr, 0, tau) / prm[3]
    vy += poly3_slope(corr, 1, tau) / prm[3]
    vz += poly3_slope(corr, 2, tau) / prm[3]
    yaw, pitch, roll = attitude(att_t, att_v, t)
    return (
        px,
        py,
        pz,
        vx,
        vy,
        vz,
        yaw + poly3(corr, 3, tau),
        pitch + poly3(corr, 4, tau),
        roll + poly3(corr, 5, tau),
        tau,
    )


@njit(cache=True, nogil=True, error_model="numpy")
def line_state(
    eph: np.ndarray, att_t: np.ndarray, att_v: np.ndarray, prm: np.ndarray, corr: np.ndarray, t: float
) -> tuple[float, float, float, Rotation]:
    """Corrected position P and rotation M = R32 R21 (navigation -> ECEF) at time t.

    The orbital frame is built from the corrected trajectory (P + dP, V + d(dP)/dt)."""
    px, py, pz, vx, vy, vz, yaw, pitch, roll, _ = corrected_state(eph, att_t, att_v, prm, corr, t)
    return px, py, pz, mat_mul(orbital_rotation(px, py, pz, vx, vy, vz), attitude_rotation(yaw, pitch, roll))


@njit(cache=True, nogil=True, error_model="numpy")
def _segment(look: np.ndarray, col: float) -> tuple[int, float]:
    """Table segment k (0..n-2) and fraction f of column coordinate col (extrapolates at the ends)."""
    x = col - 0.5
    k = min(max(int(math.floor(x)), 0), look.shape[0] - 2)
    return k, x - k


@njit(cache=True, nogil=True, error_model="numpy")
def detector_angles(look: np.ndarray, prm: np.ndarray, corr: np.ndarray, col: float) -> tuple[float, float]:
    """(psi_x, psi_y) at column coordinate col: the table, linear between detector centres, plus the
    look-angle corrections in q = (col - p_c) / 1000."""
    k, f = _segment(look, col)
    q = (col - prm[4]) * 1e-3
    return (
        look[k, 0] + f * (look[k + 1, 0] - look[k, 0]) + poly3(corr, 6, q),
        look[k, 1] + f * (look[k + 1, 1] - look[k, 1]) + poly3(corr, 7, q),
    )


@njit(cache=True, nogil=True, error_model="numpy")
def column_of(look: np.ndarray, prm: np.ndarray, corr: np.ndarray, psi_y: float) -> float:
    """Column coordinate whose (corrected) psi_y equals `psi_y`: bisection in the monotone table,
    then Newton steps for the correction polynomial."""
    n = look.shape[0]
    s = 1.0 if look[n - 1, 1] > look[0, 1] else -1.0
    lo, hi = 0, n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if s * look[mid, 1] <= s * psi_y:
            lo = mid
        else:
            hi = mid
    col = lo + 0.5 + (psi_y - look[lo, 1]) / (look[lo + 1, 1] - look[lo, 1])
    for _ in range(30):
        k, f = _segment(look, col)
        g = detector_angles(look, prm, corr, col)[1] - psi_y
        slope = look[k + 1, 1] - look[k, 1] + poly3_slope(corr, 7, (col - prm[4]) * 1e-3) * 1e-3
        step = g / slope
        col -= step
        if not abs(step) > 1e-10:
            break
    return col


@njit(cache=True, nogil=True, error_model="numpy")
def ray_height(
    px: float, py: float, pz: float, ux: float, uy: float, uz: float, h: float
) -> tuple[float, float, float, float, float]:
    """First point of the ray P + mu u (mu > 0) at ellipsoidal height h: (X, Y, Z, lon, lat), NaNs
    if none.

    Exact root of the quadratic on the ellipsoid with semi-axes (a + h, b + h) (exact for h = 0),
    then Newton steps on the geodetic height along the ray (dh/dmu = n.u, n the ellipsoid normal)
    until it is within 1e-7 m of h. Heights by `bowring` (geodesy's full conversion above 100 km)."""
    if not h > -0.5 * B:  # NaN, or a "height" inside the Earth's core
        return NAN, NAN, NAN, NAN, NAN
    a2 = (A + h) * (A + h)
    b2 = (B + h) * (B + h)
    qa = (ux * ux + uy * uy) / a2 + uz * uz / b2
    qb = 2.0 * ((px * ux + py * uy) / a2 + pz * uz / b2)
    qc = (px * px + py * py) / a2 + pz * pz / b2 - 1.0
    disc = qb * qb - 4.0 * qa * qc
    mu = (-qb - math.sqrt(disc)) / (2.0 * qa) if disc >= 0.0 else NAN
    if not mu > 0.0:
        return NAN, NAN, NAN, NAN, NAN
    for _ in range(8):
        x, y, z = px + mu * ux, py + mu * uy, pz + mu * uz
        p = math.hypot(x, y)
        cl, sl, hh = bowring(p, z)
        dh = hh - h
        if not abs(dh) > 1e-7:
            break
        mu -= dh / (cl * (x * ux + y * uy) / p + sl * uz)
    if abs(h) > 1e5:
        lon, lat, _ = ecef_to_geodetic_scalar(x, y, z)
        return x, y, z, lon, lat
    return x, y, z, math.degrees(math.atan2(y, x)), math.degrees(math.atan2(sl, cl))


@njit(cache=True, nogil=True, error_model="numpy")
def line_of_sight(
    eph: np.ndarray,
    att_t: np.ndarray,
    att_v: np.ndarray,
    look: np.ndarray,
    prm: np.ndarray,
    corr: np.ndarray,
    col: float,
    row: float,
) -> tuple[float, float, float, float, float, float]:
    """Satellite position P and unit ECEF look direction u of image point (col, row)."""
    px, py, pz, m = line_state(eph, att_t, att_v, prm, corr, prm[0] + (row - prm[1]) * prm[2])
    psi_x, psi_y = detector_angles(look, prm, corr, col)
    ux, uy, uz = look_vector(psi_x, psi_y)
    ux, uy, uz = mat_vec(m, ux, uy, uz)
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    return px, py, pz, ux / n, uy / n, uz / n


@njit(cache=True, nogil=True, error_model="numpy")
def image_to_ecef(
    eph: np.ndarray,
    att_t: np.ndarray,
    att_v: np.ndarray,
    look: np.ndarray,
    prm: np.ndarray,
    corr: np.ndarray,
    col: float,
    row: float,
    h: float,
) -> tuple[float, float, float, float, float]:
    """(X, Y, Z, lon, lat) of image point (col, row) at ellipsoidal height h (NaNs if the ray misses)."""
    px, py, pz, ux, uy, uz = line_of_sight(eph, att_t, att_v, look, prm, corr, col, row)
    return ray_height(px, py, pz, ux, uy, uz, h)


@njit(cache=True, nogil=True, error_model="numpy")
def view_angles(px: float, py: float, pz: float, m: Rotation, x: float, y: float, z: float) -> tuple[float, float]:
    """Look angles (psi_x, psi_y) of ground point X seen from P in the navigation frame M' (X - P)
    (M = R32 R21); NaNs if X is not below the satellite (n_z >= 0)."""
    nx, ny, nz = mat_t_vec(m, x - px, y - py, z - pz)
    if not nz < 0.0:
        return NAN, NAN
    return look_angles(nx, ny, nz)


@njit(cache=True, nogil=True, error_model="numpy")
def _along_track(
    eph: np.ndarray,
    att_t: np.ndarray,
    att_v: np.ndarray,
    look: np.ndarray,
    prm: np.ndarray,
    corr: np.ndarray,
    x: float,
    y: float,
    z: float,
    t: float,
) -> tuple[float, float]:
    """Along-track misfit psi_x(X) - psi_x(detector) at time t, and the detector column whose psi_y
    matches X (the view-plane condition is misfit = 0); NaNs if X is below the satellite's horizon."""
    px, py, pz, m = line_state(eph, att_t, att_v, prm, corr, t)
    if not x * (px - x) + y * (py - y) + z * (pz - z) > 0.0:
        return NAN, NAN
    nx, ny, nz = mat_t_vec(m, x - px, y - py, z - pz)
    if not nz < 0.0:
        return NAN, NAN
    gx, gy = look_angles(nx, ny, nz)
    col = column_of(look, prm, corr, gy)
    return gx - detector_angles(look, prm, corr, col)[0], col


@njit(cache=True, nogil=True, error_model="numpy")
def guess_row(guess: np.ndarray, x: float, y: float, z: float) -> float:
    """Starting row from the quadratic fit `guess` (14,): centre (3), scale, then the coefficients of
    1, u, v, w, u^2, v^2, w^2, uv, uw, vw for (u, v, w) = (X - centre) / scale."""
    u, v, w = (x - guess[0]) / guess[3], (y - guess[1]) / guess[3], (z - guess[2]) / guess[3]
    return (
        guess[4]
        + guess[5] * u
        + guess[6] * v
        + guess[7] * w
        + guess[8] * u * u
        + guess[9] * v * v
        + guess[10] * w * w
        + guess[11] * u * v
        + guess[12] * u * w
        + guess[13] * v * w
    )


@njit(cache=True, nogil=True, error_model="numpy")
def ecef_to_image(
    eph: np.ndarray,
    att_t: np.ndarray,
    att_v: np.ndarray,
    look: np.ndarray,
    prm: np.ndarray,
    corr: np.ndarray,
    guess: np.ndarray,
    x: float,
    y: float,
    z: float,
    tol: float,
    max_iter: int,
) -> tuple[float, float]:
    """(col, row) imaging ECEF point (x, y, z): secant iteration on the line time for the view-plane
    condition from the row given by `guess` (or the scene centre), the detector by inverting the
    psi_y table; stops when the row moves < tol. NaNs when it does not converge, when the point is
    beyond the horizon, or when its time lies outside the ephemeris window (no orbit extrapolation)."""
    row = guess_row(guess, x, y, z)
    t0 = prm[0] + (row - prm[1]) * prm[2] if abs(row - prm[1]) < 1e7 else prm[0]
    f0, col = _along_track(eph, att_t, att_v, look, prm, corr, x, y, z, t0)
    t1 = t0 + prm[2]
    for _ in range(max_iter):
        f1, col = _along_track(eph, att_t, att_v, look, prm, corr, x, y, z, t1)
        step = f1 * (t1 - t0) / (f1 - f0)
        if not math.isfinite(step):
            return NAN, NAN
        t0, f0 = t1, f1
        t1 = t1 - step
        if abs(step) < tol * prm[2]:
            if not eph[0, 0] <= t1 <= eph[eph.shape[0] - 1, 0]:
                return NAN, NAN
            return col, prm[1] + (t1 - prm[0]) / prm[2]
    return NAN, NAN


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def image_to_ground_kernel(
    model: PackedModel, col: np.ndarray, row: np.ndarray, h: np.ndarray, lon: np.ndarray, lat: np.ndarray
) -> None:
    """image_to_ecef of `model` (PackedModel) over arrays (lon, lat: outputs, degrees)."""
    eph, att_t, att_v, look, prm, corr = model
    for i in prange(col.size):
        lon[i], lat[i] = image_to_ecef(eph, att_t, att_v, look, prm, corr, col[i], row[i], h[i])[3:]


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def ground_to_image_kernel(
    model: PackedModel,
    guess: np.ndarray,
    lon: np.ndarray,
    lat: np.ndarray,
    h: np.ndarray,
    tol: float,
    max_iter: int,
    col: np.ndarray,
    row: np.ndarray,
) -> None:
    """ecef_to_image of `model` (PackedModel) over arrays of geodetic points (col, row: outputs)."""
    eph, att_t, att_v, look, prm, corr = model
    for i in prange(lon.size):
        x, y, z = geodetic_to_ecef_scalar(lon[i], lat[i], h[i])
        col[i], row[i] = ecef_to_image(eph, att_t, att_v, look, prm, corr, guess, x, y, z, tol, max_iter)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def line_of_sight_kernel(
    model: PackedModel, col: np.ndarray, row: np.ndarray, pos: np.ndarray, direction: np.ndarray
) -> None:
    """line_of_sight of `model` (PackedModel) over arrays (pos, direction: (n, 3) outputs)."""
    eph, att_t, att_v, look, prm, corr = model
    for i in prange(col.size):
        (pos[i, 0], pos[i, 1], pos[i, 2], direction[i, 0], direction[i, 1], direction[i, 2]) = line_of_sight(
            eph, att_t, att_v, look, prm, corr, col[i], row[i]
        )


@njit(cache=True, nogil=True, error_model="numpy")
def _moved_frame(
    px: float, py: float, pz: float, vx: float, vy: float, vz: float, r21: Rotation, x: float, y: float, z: float
) -> Vector:
    """n = R21' R32' (X - P): ground point X in the navigation frame of position P and velocity V
    (orbital frame R32 rebuilt) with attitude R21."""
    wx, wy, wz = mat_t_vec(orbital_rotation(px, py, pz, vx, vy, vz), x - px, y - py, z - pz)
    return mat_t_vec(r21, wx, wy, wz)


@njit(cache=True, nogil=True, error_model="numpy")
def _line_view(
    eph: np.ndarray,
    att_t: np.ndarray,
    att_v: np.ndarray,
    prm: np.ndarray,
    corr: np.ndarray,
    t: float,
    x: float,
    y: float,
    z: float,
) -> tuple[float, float]:
    """view_angles of X from the corrected state at time t."""
    px, py, pz, m = line_state(eph, att_t, att_v, prm, corr, t)
    return view_angles(px, py, pz, m, x, y, z)


@njit(cache=True, nogil=True, error_model="numpy")
def _angle_slopes(nx: float, ny: float, nz: float, dx: float, dy: float, dz: float) -> tuple[float, float]:
    """Change of look_angles(n) along dn: psi_x = atan(-ny / nz), psi_y = atan(nx / nz) give
    dpsi_x = (ny dnz - nz dny) / (ny^2 + nz^2), dpsi_y = (nz dnx - nx dnz) / (nx^2 + nz^2)."""
    return (ny * dz - nz * dy) / (ny * ny + nz * nz), (nz * dx - nx * dz) / (nx * nx + nz * nz)


@njit(cache=True, nogil=True, error_model="numpy")
def _geodetic_columns(
    lon: float, lat: float, h: float
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """d(X, Y, Z)/d(lon, lat, h) (row-major 9-tuple; m/degree, m/degree, m/m); with N, M the radii of
    curvature: d/dlon = (N + h) cos(lat) (-sin lon, cos lon, 0), d/dlat = (M + h) (-sin lat cos lon,
    -sin lat sin lon, cos lat), d/dh = (cos lat cos lon, cos lat sin lon, sin lat)."""
    sl, cl = math.sin(math.radians(lon)), math.cos(math.radians(lon))
    sp, cp = math.sin(math.radians(lat)), math.cos(math.radians(lat))
    w2 = 1.0 - E2 * sp * sp
    east = (A / math.sqrt(w2) + h) * cp * math.pi / 180.0
    north = (A * (1.0 - E2) / (w2 * math.sqrt(w2)) + h) * math.pi / 180.0
    return (-east * sl, -north * sp * cl, cp * cl, east * cl, -north * sp * sl, cp * sl, 0.0, north * cp, sp)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def partials_kernel(
    model: PackedModel,
    lon: np.ndarray,
    lat: np.ndarray,
    h: np.ndarray,
    col: np.ndarray,
    row: np.ndarray,
    step_m: float,
    exterior: bool,
    d_corr: np.ndarray,
    d_xyz: np.ndarray,
    d_ground: np.ndarray,
) -> None:
    """d(col, row)/d(correction coefficients) (n, 2, 32), d(col, row)/d(ECEF) (n, 2, 3) and
    d(col, row)/d(lon, lat, h) (n, 2, 3; px/degree, px/degree, px/m) of `model` (PackedModel) at the
    image points (col, row) of ground points (lon, lat, h), by the implicit function theorem on the residual
    F(col, row; X, c) = g(n) - d(col; c), n = M' (X - P) (g: look_angles, d: detector_angles,
    M = R32 R21 at t(row)): d(col, row)/dp = -[dF/d(col, row)]^-1 dF/dp.

    dF/dcol: d at col -+ 0.5; dF/drow: g at row -+ 0.5. Exact: dn/dX = M' (rows of M); with
    n = R21' w, w = R32' (X - P), and R21 = Rx(-pitch) Ry(-roll) Rz(yaw) (spot_frames):
    dn/dyaw = n x e_z, dn/dpitch = r1 x n (r1 the first row of R21), dn/droll = (sin yaw, cos yaw,
    0) x n. The corrections enter through the state at t only, so by the chain rule (q = (col -
    p_c) / 1000): position coefficient j of axis k: dF/dP_k tau^j + dF/dV_k j tau^(j-1) /
    time_scale; attitude coefficient j of angle k: dF/dangle_k tau^j; look coefficient j: dF/dpsi =
    -(q^j, 0) or -(0, q^j). dF/dP_k, dF/dV_k = dg/dn dn/dP_k, dn/dV_k, the latter by central
    differences (step_m m, step_m / time_scale m/s) with the orbital frame rebuilt from the moved
    position or velocity. dg/dn: `_angle_slopes`. d_ground = d_xyz d(X, Y, Z)/d(lon, lat, h)
    (`_geodetic_columns`). Without `exterior` the position and attitude columns (0-23) are 0, not
    computed (most of the cost)."""
    eph, att_t, att_v, look, prm, corr = model
    sv = step_m / prm[3]
    for i in prange(col.size):
        x, y, z = geodetic_to_ecef_scalar(lon[i], lat[i], h[i])
        c, r = col[i], row[i]
        t = prm[0] + (r - prm[1]) * prm[2]
        px, py, pz, vx, vy, vz, yaw, pitch, roll, tau = corrected_state(eph, att_t, att_v, prm, corr, t)
        a0, a1 = detector_angles(look, prm, corr, c + 0.5)
        b0, b1 = detector_angles(look, prm, corr, c - 0.5)
        e0, e1 = _line_view(eph, att_t, att_v, prm, corr, t + 0.5 * prm[2], x, y, z)
        g0, g1 = _line_view(eph, att_t, att_v, prm, corr, t - 0.5 * prm[2], x, y, z)
        j00, j10, j01, j11 = b0 - a0, b1 - a1, e0 - g0, e1 - g1  # dF/d(col,row), step 1
        det = j00 * j11 - j01 * j10
        # d(col, row)/dp = -J^-1 dF/dp, -J^-1 = (-j11, j01; j10, -j00) / det
        r21 = attitude_rotation(yaw, pitch, roll)
        m = mat_mul(orbital_rotation(px, py, pz, vx, vy, vz), r21)
        nx, ny, nz = mat_t_vec(m, x - px, y - py, z - pz)
        if not nz < 0.0:
            nx = ny = nz = NAN
        for k in range(3):
            f0, f1 = _angle_slopes(nx, ny, nz, m[3 * k], m[3 * k + 1], m[3 * k + 2])
            d_xyz[i, 0, k] = (j01 * f1 - j11 * f0) / det
            d_xyz[i, 1, k] = (j10 * f0 - j00 * f1) / det
        g = _geodetic_columns(lon[i], lat[i], h[i])
        for e in range(2):
            for k in range(3):
                d_ground[i, e, k] = d_xyz[i, e, 0] * g[k] + d_xyz[i, e, 1] * g[3 + k] + d_xyz[i, e, 2] * g[6 + k]
        if not exterior:
            d_corr[i, :, :24] = 0.0
        sy, cy = math.sin(yaw), math.cos(yaw)
        attitude_slopes = (
            _angle_slopes(nx, ny, nz, ny, -nx, 0.0),
            _angle_slopes(nx, ny, nz, r21[1] * nz - r21[2] * ny, r21[2] * nx - r21[0] * nz, r21[0] * ny - r21[1] * nx),
            _angle_slopes(nx, ny, nz, cy * nz, -sy * nz, sy * ny - cy * nx),
        )
        for k in range(3 if exterior else 0):
            # position and velocity of axis k, then attitude angle k
            e0, e1, e2 = (1.0 if k == 0 else 0.0), (1.0 if k == 1 else 0.0), (1.0 if k == 2 else 0.0)
            dx, dy, dz = e0 * step_m, e1 * step_m, e2 * step_m
            a0, a1, a2 = _moved_frame(px + dx, py + dy, pz + dz, vx, vy, vz, r21, x, y, z)
            b0, b1, b2 = _moved_frame(px - dx, py - dy, pz - dz, vx, vy, vz, r21, x, y, z)
            fp0, fp1 = _angle_slopes(
                nx, ny, nz, (a0 - b0) / (2 * step_m), (a1 - b1) / (2 * step_m), (a2 - b2) / (2 * step_m)
            )
            dx, dy, dz = e0 * sv, e1 * sv, e2 * sv
            a0, a1, a2 = _moved_frame(px, py, pz, vx + dx, vy + dy, vz + dz, r21, x, y, z)
            b0, b1, b2 = _moved_frame(px, py, pz, vx - dx, vy - dy, vz - dz, r21, x, y, z)
            dv = 2.0 * sv * prm[3]  # dF/dV / time_scale
            fv0, fv1 = _angle_slopes(nx, ny, nz, (a0 - b0) / dv, (a1 - b1) / dv, (a2 - b2) / dv)
            fa0, fa1 = attitude_slopes[k]
            power, below = 1.0, 0.0  # tau^j, j tau^(j-1)
            for j in range(4):
                f0, f1 = fp0 * power + fv0 * below, fp1 * power + fv1 * below
                d_corr[i, 0, 4 * k + j] = (j01 * f1 - j11 * f0) / det
                d_corr[i, 1, 4 * k + j] = (j10 * f0 - j00 * f1) / det
                d_corr[i, 0, 12 + 4 * k + j] = (j01 * fa1 - j11 * fa0) * power / det
                d_corr[i, 1, 12 + 4 * k + j] = (j10 * fa0 - j00 * fa1) * power / det
                below = (j + 1) * power
                power *= tau
        q = (c - prm[4]) * 1e-3
        power = 1.0
        for j in range(4):
            d_corr[i, 0, 24 + j] = j11 * power / det
            d_corr[i, 1, 24 + j] = -j10 * power / det
            d_corr[i, 0, 28 + j] = -j01 * power / det
            d_corr[i, 1, 28 + j] = j00 * power / det
            power *= q


@njit(cache=True, nogil=True, error_model="numpy")
def _geodetic_along(px: float, py: float, pz: float, ux: float, uy: float, uz: float, mu: float) -> Vector:
    """(lon, lat, h) of the ray point P + mu u (near the Earth's surface, see `bowring`)."""
    x, y, z = px + mu * ux, py + mu * uy, pz + mu * uz
    cl, sl, h = bowring(math.hypot(x, y), z)
    return math.degrees(math.atan2(y, x)), math.degrees(math.atan2(sl, cl)), h


@njit(cache=True, nogil=True, error_model="numpy")
def _quadratic(f0: float, f1: float, f2: float, s: float) -> float:
    """Value at s in [0, 1] of the parabola through (0, f0), (0.5, f1), (1, f2)."""
    return f0 + s * (-3.0 * f0 + 4.0 * f1 - f2) + 2.0 * s * s * (f0 - 2.0 * f1 + f2)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def image_to_dem_kernel(
    model: PackedModel,
    col: np.ndarray,
    row: np.ndarray,
    grid: np.ndarray,
    gt: np.ndarray,
    hmin: float,
    hmax: float,
    samples: int,
    tol: float,
    out: np.ndarray,
) -> None:
    """First intersection of each line of sight of `model` (PackedModel) with the DEM `grid` of
    geotransform `gt` (out: (n, 3) lon, lat, h; NaNs where none).

    The ray segment between heights hmax and hmin is scanned from the top in equal steps of mu, at
    least `samples` of them and at most a quarter of a DEM cell apart horizontally (so a cliff, a
    needle or a wall one cell wide is not stepped over on oblique rays); geodetic coordinates along it
    come from a parabola through three exact conversions (error of the order of mm over 10 km of
    ray), so the scan costs a DEM lookup per sample. The first sample pair where h - dem goes from
    >= 0 to <= 0 is refined by regula falsi (Illinois) with exact conversions to `tol` metres."""
    eph, att_t, att_v, look, prm, corr = model
    lon0, dlon, lat0, dlat = gt[0], gt[1], gt[3], gt[5]
    for i in prange(col.size):
        out[i, 0] = out[i, 1] = out[i, 2] = NAN
        px, py, pz, ux, uy, uz = line_of_sight(eph, att_t, att_v, look, prm, corr, col[i], row[i])
        xt, yt, zt = ray_height(px, py, pz, ux, uy, uz, hmax)[:3]
        xb, yb, zb = ray_height(px, py, pz, ux, uy, uz, hmin)[:3]
        mu_t = (xt - px) * ux + (yt - py) * uy + (zt - pz) * uz
        mu_b = (xb - px) * ux + (yb - py) * uy + (zb - pz) * uz
        if not (mu_b > mu_t):
            continue
        lo0, la0, h0 = _geodetic_along(px, py, pz, ux, uy, uz, mu_t)
        lo1, la1, h1 = _geodetic_along(px, py, pz, ux, uy, uz, 0.5 * (mu_t + mu_b))
        lo2, la2, h2 = _geodetic_along(px, py, pz, ux, uy, uz, mu_b)
        lo1 = lo0 + (lo1 - lo0 + 540.0) % 360.0 - 180.0
        lo2 = lo0 + (lo2 - lo0 + 540.0) % 360.0 - 180.0
        cells = max(abs(lo2 - lo0) / abs(dlon), abs(la2 - la0) / abs(dlat))
        if not math.isfinite(cells):
            continue
        steps = max(samples, int(math.ceil(4.0 * cells)))
        f_prev = NAN
        s_prev = 0.0
        a = b = fa = fb = NAN
        for k in range(steps + 1):
            s = k / steps
            lon = _quadratic(lo0, lo1, lo2, s)
            lat = _quadratic(la0, la1, la2, s)
            f = _quadratic(h0, h1, h2, s) - bilinear_scalar(grid, lon0, dlon, lat0, dlat, lon, lat)
            if f_prev >= 0.0 and f <= 0.0:
                a, fa, b, fb = s_prev, f_prev, s, f
                break
            f_prev, s_prev = f, s
        if not math.isfinite(a):
            continue
        length = mu_b - mu_t
        side = 0
        for _ in range(100):
            s = a - fa * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
            if not (a < s < b):
                s = 0.5 * (a + b)
            lon, lat, h = _geodetic_along(px, py, pz, ux, uy, uz, mu_t + s * length)
            f = h - bilinear_scalar(grid, lon0, dlon, lat0, dlat, lon, lat)
            if not math.isfinite(f):
                f = -1.0
            out[i, 0], out[i, 1], out[i, 2] = lon, lat, h
            if abs(f) < tol or (b - a) * length < tol:
                break
            if f > 0.0:
                a, fa = s, f
                if side == 1:
                    fb *= 0.5
                side = 1
            else:
                b, fb = s, f
                if side == -1:
                    fa *= 0.5
                side = -1
