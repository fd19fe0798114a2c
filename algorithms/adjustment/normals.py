"""numba kernels of the bundle adjustment: normal equations with the object points eliminated per
point (Schur complement), back-substitution and the per-observation statistics.

Per measurement j of point p (2 image equations): v_j = A_j dX_p + B_j do - l_j, weight W_j =
diag(w_j); A_j (2, 3) px per metre east/north/up, B_j (2, K) px per unit of the K orientation
unknowns the image depends on, `col[img_j, k]` their index among the free unknowns (-1: fixed).
Ground observations of control points: v = dX_p - l_g with weights Wg_p (3, diagonal).

    N_pp = sum_j A_j' W A_j + Wg_p,   b_p = sum_j A_j' W l_j + Wg_p l_g,   C_j = A_j' W B_j
    N    = sum_j B_j' W B_j - sum_p (sum_j C_j)' N_pp^-1 (sum_k C_k)
    b    = sum_j B_j' W l_j - sum_p (sum_j C_j)' N_pp^-1 b_p
    dX_p = N_pp^-1 (b_p - sum_j C_j do)

so the cost grows linearly with the number of points.

The kernels here and the sensor models' are parallel over points. A block adjustment calls them many
times on small arrays (the automatic selection runs dozens of adjustments of a few hundred points):
there, starting a parallel region and the idle threads' spinning cost more than the work, so
`kernel_threads` runs them on the calling thread below SERIAL_MEASUREMENTS image measurements. The
results do not depend on it: the points are reduced in CHUNKS chunks whatever the threads.

The kernels take the image observations as one `Design` and the per-point results as one `PointBlocks`
(NamedTuples of arrays, which numba compiles)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from typing import NamedTuple

import numba
import numpy as np
from numba import njit, prange

#: below this many image measurements the adjustment's kernels run on the calling thread (module docstring)
SERIAL_MEASUREMENTS = 20000


@contextlib.contextmanager
def kernel_threads(measurements: int) -> Iterator[None]:
    """Run the numba kernels called inside on the calling thread alone when `measurements` is below
    SERIAL_MEASUREMENTS (numba's thread count is per calling thread: other threads are not affected);
    the previous count is restored on leaving."""
    saved = numba.get_num_threads()
    if measurements < SERIAL_MEASUREMENTS:
        numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(saved)


@njit(cache=True, nogil=True)
def scatter_partials(rows, d_corr, d_ground, per_metre, coef, cols, values, b, a):
    """Measurements `rows` of one image: b[rows[i]] = d_corr[i] @ M, M its (n_coefficients, K)
    coefficient -> compact-column map given by its non-zero entries M[coef[t], cols[t]] = values[t],
    and a[rows[i]] = d_ground[i] * per_metre[i] (px per degree -> px per metre east/north, px per metre
    up)."""
    kk = b.shape[2]
    for i in range(rows.size):
        j = rows[i]
        for e in range(2):
            for k in range(kk):
                b[j, e, k] = 0.0
            for t in range(coef.size):
                b[j, e, cols[t]] += d_corr[i, e, coef[t]] * values[t]
            for r in range(3):
                a[j, e, r] = d_ground[i, e, r] * per_metre[i, r]


@njit(cache=True, nogil=True)
def _inv3(m, out):
    """out = m^-1 for a symmetric 3 x 3; returns the determinant (0: singular, out untouched)."""
    c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
    scale = abs(m[0, 0] * m[1, 1] * m[2, 2])
    if scale == 0.0 or abs(det) < 1e-12 * scale:
        return 0.0
    out[0, 0] = c00 / det
    out[0, 1] = (m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]) / det
    out[0, 2] = (m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]) / det
    out[1, 0] = c01 / det
    out[1, 1] = (m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]) / det
    out[1, 2] = (m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]) / det
    out[2, 0] = c02 / det
    out[2, 1] = (m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]) / det
    out[2, 2] = (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]) / det
    return det


@njit(cache=True, nogil=True)
def cholesky_solve(m, rhs, out):
    """out = m^-1 rhs (rhs (n, k)) for a symmetric positive definite m, by m = L L' and two
    triangular solves; False (out untouched) where a pivot is not positive. The reduced normal
    equations are small (the free orientation unknowns): solved here rather than by LAPACK, whose
    threads contend with the parallel kernels' waiting ones on a 2-core machine
    (docs/validation.md#cholesky-solve)."""
    n = m.shape[0]
    low = np.zeros((n, n))
    for j in range(n):
        d = m[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        if not d > 0.0:
            return False
        low[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            t = m[i, j]
            for k in range(j):
                t -= low[i, k] * low[j, k]
            low[i, j] = t / low[j, j]
    for c in range(rhs.shape[1]):
        for i in range(n):  # L y = rhs
            t = rhs[i, c]
            for k in range(i):
                t -= low[i, k] * out[k, c]
            out[i, c] = t / low[i, i]
        for i in range(n - 1, -1, -1):  # L' x = y
            t = out[i, c]
            for k in range(i + 1, n):
                t -= low[k, i] * out[k, c]
            out[i, c] = t / low[i, i]
    return True


#: points are reduced in this many chunks, in parallel, each with its own partial sums
CHUNKS = 16


class Design(NamedTuple):
    """The image observations sorted by point (module docstring): measurements start[p]:start[p + 1] are
    point p's; a (M, 2, 3) px per metre east/north/up, b (M, 2, K) px per orientation unknown, w (M, 2)
    weights, img (M,) the image of each measurement, col (n_images, K) its unknowns' free columns (-1:
    fixed)."""

    start: np.ndarray
    a: np.ndarray
    b: np.ndarray
    w: np.ndarray
    img: np.ndarray
    col: np.ndarray


class Ground(NamedTuple):
    """The ground observations of the points: weights w (P, 3, diagonal: 0 but for control points) and
    misclosures l (P, 3, m east/north/up)."""

    w: np.ndarray
    l: np.ndarray


class PointBlocks(NamedTuple):
    """Per point: ninv (P, 3, 3) N_pp^-1, bp (P, 3) b_p, ok (P,) False where N_pp is singular."""

    ninv: np.ndarray
    bp: np.ndarray
    ok: np.ndarray


@njit(cache=True, nogil=True, parallel=True)
def reduce_normals(
    design: Design,
    l: np.ndarray,
    ground: Ground,
    nfree: int,
    normal: np.ndarray,
    rhs: np.ndarray,
    points: PointBlocks,
) -> float:
    """Accumulate the reduced normal equations (module docstring) of the image observations `design` with
    misclosures l (M, 2) and the `ground` observations into normal (nfree, nfree) and rhs (nfree,); store
    N_pp^-1, b_p and whether N_pp is regular in `points` (a singular point is left out). Returns sum of
    l' W l (the weighted squared misclosures). The points run in CHUNKS chunks in parallel, each summing
    into its own copy of N and b."""
    npts = design.start.size - 1
    chunks = max(1, min(CHUNKS, npts))
    normals = np.zeros((chunks, nfree, nfree))
    rhss = np.zeros((chunks, nfree))
    costs = np.zeros(chunks)
    for k in prange(chunks):
        npp = np.empty((3, 3))
        c = np.zeros((3, nfree))
        used = np.zeros(nfree, np.bool_)
        for p in range(k * npts // chunks, (k + 1) * npts // chunks):
            costs[k] += _reduce_point(p, design, l, ground, nfree, normals[k], rhss[k], points, npp, c, used)
    for k in range(chunks):
        normal += normals[k]
        rhs += rhss[k]
    return costs.sum()


@njit(cache=True, nogil=True)
def _reduce_point(
    p: int,
    design: Design,
    l: np.ndarray,
    ground: Ground,
    nfree: int,
    normal: np.ndarray,
    rhs: np.ndarray,
    points: PointBlocks,
    npp: np.ndarray,
    c: np.ndarray,
    used: np.ndarray,
) -> float:
    """Point p's part of reduce_normals (npp, c, used: work arrays, c and used left cleared);
    returns its weighted squared misclosures."""
    start, a, b, w, img, col = design
    wg, lg = ground
    ninv, bp, ok = points
    kk = b.shape[2]
    cost = 0.0
    npp[:, :] = 0.0
    for r in range(3):
        npp[r, r] = wg[p, r]
        bp[p, r] = wg[p, r] * lg[p, r]
        cost += wg[p, r] * lg[p, r] * lg[p, r]
    for j in range(start[p], start[p + 1]):
        for e in range(2):
            we = w[j, e]
            cost += we * l[j, e] * l[j, e]
            for r in range(3):
                bp[p, r] += a[j, e, r] * we * l[j, e]
                for s in range(3):
                    npp[r, s] += a[j, e, r] * we * a[j, e, s]
    ok[p] = _inv3(npp, ninv[p]) != 0.0
    if not ok[p]:
        return cost
    # C = sum_j A_j' W B_j scattered to free columns; orientation blocks
    for j in range(start[p], start[p + 1]):
        cj = col[img[j]]
        for k in range(kk):
            q = cj[k]
            if q < 0:
                continue
            used[q] = True
            for e in range(2):
                wb = w[j, e] * b[j, e, k]
                rhs[q] += wb * l[j, e]
                for r in range(3):
                    c[r, q] += a[j, e, r] * wb
                for k2 in range(kk):
                    q2 = cj[k2]
                    if q2 >= 0:
                        normal[q, q2] += wb * b[j, e, k2]
    # Schur complement over the columns this point touches
    for q in range(nfree):
        if not used[q]:
            continue
        t0 = ninv[p, 0, 0] * c[0, q] + ninv[p, 0, 1] * c[1, q] + ninv[p, 0, 2] * c[2, q]
        t1 = ninv[p, 1, 0] * c[0, q] + ninv[p, 1, 1] * c[1, q] + ninv[p, 1, 2] * c[2, q]
        t2 = ninv[p, 2, 0] * c[0, q] + ninv[p, 2, 1] * c[1, q] + ninv[p, 2, 2] * c[2, q]
        rhs[q] -= t0 * bp[p, 0] + t1 * bp[p, 1] + t2 * bp[p, 2]
        for q2 in range(nfree):
            if used[q2]:
                normal[q, q2] -= t0 * c[0, q2] + t1 * c[1, q2] + t2 * c[2, q2]
    for q in range(nfree):
        if used[q]:
            used[q] = False
            c[0, q] = c[1, q] = c[2, q] = 0.0
    return cost


@njit(cache=True, nogil=True)
def back_substitute(design: Design, points: PointBlocks, do: np.ndarray, dx: np.ndarray) -> None:
    """dx[p] = N_pp^-1 (b_p - sum_j C_j do) (module docstring) of the `points` reduce_normals filled; NaN
    where not ok."""
    start, a, b, w, img, col = design
    ninv, bp, ok = points
    kk = b.shape[2]
    g = np.empty(3)
    for p in range(start.size - 1):
        if not ok[p]:
            dx[p, :] = np.nan
            continue
        g[:] = bp[p]
        for j in range(start[p], start[p + 1]):
            cj = col[img[j]]
            for e in range(2):
                bd = 0.0
                for k in range(kk):
                    if cj[k] >= 0:
                        bd += b[j, e, k] * do[cj[k]]
                for r in range(3):
                    g[r] -= a[j, e, r] * w[j, e] * bd
        for r in range(3):
            dx[p, r] = ninv[p, r, 0] * g[0] + ninv[p, r, 1] * g[1] + ninv[p, r, 2] * g[2]


@njit(cache=True, nogil=True)
def point_statistics(
    design: Design, points: PointBlocks, qoo: np.ndarray, qpp: np.ndarray, redundancy: np.ndarray
) -> None:
    """Cofactors qpp (P, 3, 3) of the points and redundancy numbers (M, 2) of the image observations, from
    the cofactors qoo of the orientation unknowns and the `points` reduce_normals filled.

    G_p = -N_pp^-1 sum_j C_j;  Q_pp = N_pp^-1 + G_p Q_oo G_p';  Q_po = G_p Q_oo;
    for an observation row (a, b) of point p: q = a Q_pp a' + 2 a Q_po b' + b Q_oo b', and its
    redundancy number is r = 1 - q w."""
    start, a, b, w, img, col = design
    ninv, _, ok = points
    kk = b.shape[2]
    nfree = qoo.shape[0]
    c = np.zeros((3, nfree))
    g = np.zeros((3, nfree))
    qpo = np.zeros((3, nfree))
    for p in range(start.size - 1):
        if not ok[p]:
            qpp[p, :, :] = np.nan
            for j in range(start[p], start[p + 1]):
                redundancy[j, 0] = redundancy[j, 1] = np.nan
            continue
        c[:, :] = 0.0
        for j in range(start[p], start[p + 1]):
            cj = col[img[j]]
            for k in range(kk):
                q = cj[k]
                if q >= 0:
                    for e in range(2):
                        for r in range(3):
                            c[r, q] += a[j, e, r] * w[j, e] * b[j, e, k]
        for r in range(3):
            for q in range(nfree):
                g[r, q] = -(ninv[p, r, 0] * c[0, q] + ninv[p, r, 1] * c[1, q] + ninv[p, r, 2] * c[2, q])
        for r in range(3):
            for q in range(nfree):
                acc = 0.0
                for q2 in range(nfree):
                    acc += g[r, q2] * qoo[q2, q]
                qpo[r, q] = acc
        for r in range(3):
            for s in range(3):
                acc = ninv[p, r, s]
                for q in range(nfree):
                    acc += qpo[r, q] * g[s, q]
                qpp[p, r, s] = acc
        for j in range(start[p], start[p + 1]):
            cj = col[img[j]]
            for e in range(2):
                qa = 0.0
                for r in range(3):
                    for s in range(3):
                        qa += a[j, e, r] * qpp[p, r, s] * a[j, e, s]
                for k in range(kk):
                    q = cj[k]
                    if q < 0:
                        continue
                    for r in range(3):
                        qa += 2.0 * a[j, e, r] * qpo[r, q] * b[j, e, k]
                    for k2 in range(kk):
                        q2 = cj[k2]
                        if q2 >= 0:
                            qa += b[j, e, k] * qoo[q, q2] * b[j, e, k2]
                redundancy[j, e] = 1.0 - qa * w[j, e]
