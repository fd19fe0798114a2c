"""Numba core of multi-photo geometrically constrained least-squares matching (the model is in
mpgc.py's docstring).

Images reach the kernels packed: `buf` holds the windows of the reference image (index 0) and
of the n search images (1..n) one after the other, flattened; meta[i] = (start, rows, cols) of
window i in `buf`, offs[i] = (x, y) of its top-left corner in full-image GDAL coordinates.
Positions in `cen`, `state`, x0, y0 are full-image coordinates.

Per point: state (n, 8) = per search image (x, a1, a2, y, a4, a5, r0, r1); dx (3,) = the object
point in metres (E, N, U) from the linearisation point, at which cen (n + 1, 2) = f_i(X) and jac
(n + 1, 2, 3) = d(col, row)/d(E, N, U) in px/m were evaluated (row 0: the reference image).
out (out_size(n)): per search image (rho, semi-major, semi-minor of the error ellipse), then the
covariance of (E, N, U) (ee, en, eu, nn, nu, uu; m^2; both the sandwich N^-1 M N^-1), sigma0 (DN),
v'Pv and redundancy of the geometric observations, RMS of the geometric residuals (px)."""

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..interpolation import cubic
from .lsm import NOT_CONVERGED, OK, OUTSIDE, REWEIGHTINGS, SINGULAR, _chol_solve, _cholesky, _window_inside, template
from .params import TUKEY_C

#: unknowns per search image: x, a1, a2, y, a4, a5, r0, r1
NPI = 8
#: unknowns of the object point: dE, dN, dU
NPX = 3
#: samples per side of the box whose mean grey value the support weights compare (support_weights)
SUPPORT_BOX = 5
#: out fields after the 3 per search image
COV, SIGMA0, GEO_VTPV, GEO_RED, GEO_RMS = 0, 6, 7, 8, 9
_TAIL = 10


@njit(cache=True, nogil=True)
def out_size(n):
    """Length of the kernel's output vector for n search images."""
    return 3 * n + _TAIL


@njit(cache=True, nogil=True)
def window(buf, meta, i):
    """Window i of the packed images as a 2-D array."""
    s = meta[i, 0]
    return buf[s : s + meta[i, 1] * meta[i, 2]].reshape((meta[i, 1], meta[i, 2]))


@njit(cache=True, nogil=True)
def grey_weights(rep, pw):
    """Weights of the grey-level equations of each search image, pw_i = 1 / (1 + rep_i): the
    inverse variance (in units of the noise variance of one image) of template noise plus image-i
    noise at unit gain. They do not depend on r1: weights that grow as r1 -> 0 (the inverse of the
    covariance noise_covariance describes) make r1 -> 0, f fitted by a constant, win on weak texture."""
    for i in range(rep.shape[0]):
        pw[i] = 1.0 / (1.0 + rep[i])


@njit(cache=True, nogil=True)
def support_weights(f, half, centre, gamma, cw):
    """Support weights of the template samples (mpgc.py), row-major like f:
    cw(k, l) = exp(-(k^2 + l^2) / (2 centre^2)) exp(-(m(k, l) - m(0, 0))^2 / (2 gamma^2)), m the mean
    of f over the SUPPORT_BOX^2 samples around (k, l) inside the template (DN; gamma = similarity
    times the template's standard deviation); a factor is 1 where its parameter is 0."""
    nside = 2 * half + 1
    hb = SUPPORT_BOX // 2
    if gamma > 0.0:  # box means first (cw), then the weights in place
        for r in range(nside):
            for c in range(nside):
                acc = 0.0
                cnt = 0
                for rr in range(max(0, r - hb), min(nside, r + hb + 1)):
                    for cc in range(max(0, c - hb), min(nside, c + hb + 1)):
                        acc += f[rr * nside + cc]
                        cnt += 1
                cw[r * nside + c] = acc / cnt
    mc = cw[half * nside + half] if gamma > 0.0 else 0.0
    for r in range(nside):
        for c in range(nside):
            idx = r * nside + c
            w = math.exp(-0.5 * float((r - half) ** 2 + (c - half) ** 2) / (centre * centre)) if centre > 0.0 else 1.0
            if gamma > 0.0:
                u = (cw[idx] - mc) / gamma
                w *= math.exp(-0.5 * u * u)
            cw[idx] = w


@njit(cache=True, nogil=True)
def noise_covariance(pw, r1, rep, c):
    """c = diag(pw) (1 1' + diag(r1_i^2 rep_i)) diag(pw): the covariance of the weighted grey-level
    equations of one template sample (units of the noise variance), which share the template's
    noise (the middle of the sandwich covariance)."""
    n = pw.shape[0]
    for i in range(n):
        for j in range(n):
            c[i, j] = pw[i] * pw[j]
        c[i, i] *= 1.0 + r1[i] * r1[i] * rep[i]


@njit(cache=True, nogil=True)
def _geo_row(i, c, x0, y0, cen, jac, state, dx, coef):
    """Geometric observation c (0: col, 1: row) of image i: coefficients on (dE, dN, dU) in coef
    (the shift's coefficient is 1 for search images), column of the shift (-1 for the reference)
    and the residual at the current state: reference x0 - f_0(X), search f_i(X) - x_i."""
    proj = cen[i, c]
    for p in range(NPX):
        proj += jac[i, c, p] * dx[p]
    if i == 0:
        for p in range(NPX):
            coef[p] = jac[0, c, p]
        return -1, (x0 if c == 0 else y0) - proj
    for p in range(NPX):
        coef[p] = -jac[i, c, p]
    col = NPX + NPI * (i - 1) + 3 * c
    return col, proj - state[i - 1, 3 * c]


class Stack(NamedTuple):
    """The images' windows of a batch of points, packed: `buf` the pixels, `meta` each window's place in it
    (`window`), `offs` each window's top-left image position."""

    buf: np.ndarray
    meta: np.ndarray
    offs: np.ndarray


class Solve(NamedTuple):
    """MPGC's solution settings: template half-size (px), largest number of iterations, convergence (px), the a
    priori sigma of the geometric observations (px), and the support weights' centre sigma and similarity (0:
    off; support_weights)."""

    half: int
    max_iter: int
    conv: float
    sigma_g: float
    centre: float
    similarity: float


@njit(cache=True, nogil=True)
def mpgc_point(stack, x0, y0, cen, jac, state, dx, solve, out):
    """Gauss-Newton MPGC of one point from the given state (updated in place) in the windows `stack` (Stack) with
    the settings `solve` (Solve); fills out. Returns (status, iterations): 0 ok, 1 a window leaves its image, 2
    singular normal equations (flat texture, degenerate affine), 3 not converged within max_iter (state and out
    hold the last iteration)."""
    buf, meta, offs = stack
    half, max_iter, conv, sigma_g, centre, similarity = solve
    for i in range(out.shape[0]):
        out[i] = np.nan
    n = state.shape[0]
    npar = NPX + NPI * n
    nside = 2 * half + 1
    ns = nside * nside
    f = np.empty(ns)
    fk = np.empty(ns)
    fl = np.empty(ns)
    if not template(window(buf, meta, 0), x0 - offs[0, 0], y0 - offs[0, 1], half, f, fk, fl):
        return OUTSIDE, 0
    sf = 0.0
    sff = 0.0
    for idx in range(ns):
        sf += f[idx]
        sff += f[idx] * f[idx]
    cw = np.empty(ns)
    support_weights(f, half, centre, similarity * math.sqrt(max(sff / ns - (sf / ns) ** 2, 0.0)), cw)
    nmat = np.empty((npar, npar))
    b = np.empty(npar)
    d = np.empty(npar)
    mmat = np.empty((npar, npar))
    pw = np.empty(n)
    cn = np.empty((n, n))
    ia = np.empty((n, 4))
    rep = np.empty(n)
    r1 = np.empty(n)
    arow = np.empty((ns, n, NPI))  # the iteration's design rows, kept for M (_middle)
    geo = np.empty((2 * (n + 1), NPX))  # the iteration's geometric rows' coefficients ...
    gcol = np.empty(2 * (n + 1), np.int64)  # ... and shift columns
    obs = np.empty(n)
    sg = np.empty(n)
    sgg = np.empty(n)
    sfg = np.empty(n)
    svv = np.empty(n)
    sw = np.empty(n)
    cs = np.zeros(n)  # per search image Tukey's c times its residual scale
    wbuf = np.empty((ns, n))
    for idx in range(ns):
        for i in range(n):
            wbuf[idx, i] = cw[idx]
    skap = np.empty(n)
    coef = np.empty(NPX)
    it = 0
    converged = False
    s2 = 0.0
    wg = 1.0 / (sigma_g * sigma_g)
    while it < max_iter:
        for i in range(n):
            img = window(buf, meta, i + 1)
            xs = state[i, 0] - offs[i + 1, 0]
            ys = state[i, 3] - offs[i + 1, 1]
            a1, a2, a4, a5 = state[i, 1], state[i, 2], state[i, 4], state[i, 5]
            if (
                not (math.isfinite(xs) and math.isfinite(ys))
                or img.shape[0] < 4
                or img.shape[1] < 4
                or not _window_inside(img.shape[0], img.shape[1], xs, ys, a1, a2, a4, a5, half)
            ):
                return OUTSIDE, it
            det = a1 * a5 - a2 * a4
            if not abs(det) > 1e-6:
                return SINGULAR, it
            ia[i, 0] = a5 / det
            ia[i, 1] = -a2 / det
            ia[i, 2] = -a4 / det
            ia[i, 3] = a1 / det
            # image-i noise repeats on 1 / |det| template samples when image i is coarser (lsm.py)
            rep[i] = 1.0 / abs(det) if abs(det) < 1.0 else 1.0
            r1[i] = state[i, 7]
        grey_weights(rep, pw)
        noise_covariance(pw, r1, rep, cn)
        nmat[:, :] = 0.0
        b[:] = 0.0
        sg[:] = 0.0
        sgg[:] = 0.0
        sfg[:] = 0.0
        svv[:] = 0.0
        skap[:] = 0.0
        sw[:] = 0.0
        idx = 0
        for l in range(-half, half + 1):
            fl_ = float(l)
            for k in range(-half, half + 1):
                fk_ = float(k)
                fv = f[idx]
                for i in range(n):
                    xs = state[i, 0] - offs[i + 1, 0] + state[i, 1] * fk_ + state[i, 2] * fl_
                    ys = state[i, 3] - offs[i + 1, 1] + state[i, 4] * fk_ + state[i, 5] * fl_
                    g, kap = cubic(window(buf, meta, i + 1), xs, ys)
                    o = fv - (state[i, 6] + state[i, 7] * g)
                    # (r1 gx, r1 gy) = A^-T (fk, fl): template gradients through the affine (lsm.py)
                    gx = ia[i, 0] * fk[idx] + ia[i, 2] * fl[idx]
                    gy = ia[i, 1] * fk[idx] + ia[i, 3] * fl[idx]
                    a = arow[idx, i]
                    a[0] = gx
                    a[1] = gx * fk_
                    a[2] = gx * fl_
                    a[3] = gy
                    a[4] = gy * fk_
                    a[5] = gy * fl_
                    a[6] = 1.0
                    a[7] = g
                    obs[i] = o
                    if 0 < it <= REWEIGHTINGS:  # Tukey's biweight (mpgc.py)
                        u = o / cs[i] if cs[i] > 0.0 else 0.0
                        wbuf[idx, i] = cw[idx] * (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0
                    w = wbuf[idx, i]
                    sw[i] += w
                    sg[i] += g
                    sgg[i] += g * g
                    sfg[i] += fv * g
                    svv[i] += w * o * o
                    skap[i] += kap
                # N: pw_i w_i a_i a_i' (M, the sandwich's middle, from the last iteration's rows: _middle)
                for i in range(n):
                    bi = NPX + NPI * i
                    wi = pw[i] * wbuf[idx, i]
                    for p in range(NPI):
                        t = arow[idx, i, p]
                        b[bi + p] += wi * t * obs[i]
                        for q in range(p, NPI):
                            nmat[bi + p, bi + q] += wi * t * arow[idx, i, q]
                idx += 1
        # noise variance of one image (DN^2) from the residuals: image i's residual variance is
        # s2 (1 + r1_i^2 kappa_i) (template noise plus resampled image-i noise)
        s2 = 0.0
        red = 0.0
        for i in range(n):
            s2 += svv[i] / (1.0 + r1[i] * r1[i] * skap[i] / ns)
            red += max(sw[i] - NPI, 1.0)
        s2 /= red
        s2 = max(s2, 1e-10)
        for p in range(NPX, npar):
            b[p] /= s2
            for q in range(p, npar):
                nmat[p, q] /= s2
        for i in range(n + 1):
            for c in range(2):
                col, r = _geo_row(i, c, x0, y0, cen, jac, state, dx, coef)
                geo[2 * i + c] = coef
                gcol[2 * i + c] = col
                for p in range(NPX):
                    b[p] += wg * coef[p] * r
                    for q in range(p, NPX):
                        nmat[p, q] += wg * coef[p] * coef[q]
                    if col >= 0:
                        nmat[p, col] += wg * coef[p]
                if col >= 0:
                    b[col] += wg * r
                    nmat[col, col] += wg
        if not _cholesky(nmat, npar):
            return SINGULAR, it
        _chol_solve(nmat, b, d, npar)
        ok = True
        for p in range(npar):
            ok = ok and math.isfinite(d[p])
        if not ok:
            return SINGULAR, it
        for p in range(NPX):
            dx[p] += d[p]
        for i in range(n):
            for p in range(NPI):
                state[i, p] += d[NPX + NPI * i + p]
        it += 1
        for i in range(n):
            cs[i] = TUKEY_C * math.sqrt(svv[i] / sw[i]) if sw[i] > 0.0 else 0.0
        # largest position change in any image (reference: the projection of the object point)
        step = 0.0
        for i in range(n + 1):
            ux = 0.0
            uy = 0.0
            for p in range(NPX):
                ux += jac[i, 0, p] * d[p]
                uy += jac[i, 1, p] * d[p]
            step = max(step, math.sqrt(ux * ux + uy * uy))
            if i > 0:
                bi = NPX + NPI * (i - 1)
                step = max(step, math.sqrt(d[bi] * d[bi] + d[bi + 3] * d[bi + 3]))
        if step < conv:
            converged = True
            break
    if it == 0:
        return NOT_CONVERGED, 0
    _middle(Rows(arow, wbuf, cn, geo, gcol), s2, wg, mmat)
    _precision(nmat, mmat, n, npar, x0, y0, cen, jac, state, dx, wg, out)
    nf = float(ns)
    vf = sff - sf * sf / nf
    for i in range(n):
        vg = sgg[i] - sg[i] * sg[i] / nf
        cfg = sfg[i] - sf * sg[i] / nf
        out[3 * i] = cfg / math.sqrt(vf * vg) if vf > 0.0 and vg > 0.0 else 0.0
    out[3 * n + SIGMA0] = math.sqrt(s2)
    return (OK if converged else NOT_CONVERGED), it


class Rows(NamedTuple):
    """One iteration's design: the grey-level rows `arow` (sample, search image, unknown), their robust weights
    `wbuf` (sample, search image), the noise covariance `cn` of one sample's equations (noise_covariance), and
    the geometric rows' coefficients `geo` on (dE, dN, dU) with their shift columns `gcol` (_geo_row)."""

    arow: np.ndarray
    wbuf: np.ndarray
    cn: np.ndarray
    geo: np.ndarray
    gcol: np.ndarray


@njit(cache=True, nogil=True)
def _middle(rows, s2, wg, mmat):
    """The sandwich's middle M (upper triangle) of one iteration's design `rows` (Rows), the grey-level part
    in units of s2 (DN^2): sum over samples of w_i w_j cn_ij a_i a_j' / s2, plus the geometric rows' wg g g'.
    Built once, for the last iteration, the only one the covariance reads; the sums run in the order of the
    samples, as N's, so M is the same to the bit as one built alongside N at every iteration."""
    arow, wbuf, cn, geo, gcol = rows
    ns, n = wbuf.shape
    npar = mmat.shape[0]
    mmat[:, :] = 0.0
    for idx in range(ns):
        for i in range(n):
            bi = NPX + NPI * i
            wm = wbuf[idx, i] * wbuf[idx, i] * cn[i, i]
            for p in range(NPI):
                t = arow[idx, i, p]
                for q in range(p, NPI):
                    mmat[bi + p, bi + q] += wm * t * arow[idx, i, q]
            for j in range(i + 1, n):
                bj = NPX + NPI * j
                wm = wbuf[idx, i] * wbuf[idx, j] * cn[i, j]
                for p in range(NPI):
                    t = wm * arow[idx, i, p]
                    for q in range(NPI):
                        mmat[bi + p, bj + q] += t * arow[idx, j, q]
    for p in range(NPX, npar):
        for q in range(p, npar):
            mmat[p, q] /= s2
    for r in range(geo.shape[0]):
        coef, col = geo[r], gcol[r]
        for p in range(NPX):
            for q in range(p, NPX):
                mmat[p, q] += wg * coef[p] * coef[q]
            if col >= 0:
                mmat[p, col] += wg * coef[p]
        if col >= 0:
            mmat[col, col] += wg


@njit(cache=True, nogil=True)
def _precision(lower, mmat, n, npar, x0, y0, cen, jac, state, dx, wg, out):
    """From the last normal equations N (its Cholesky factor) and the sandwich's middle M (upper
    triangle): covariance N^-1 M N^-1 of the search positions (error ellipses) and of (E, N, U);
    v'Pv, redundancy (sum of the redundancy numbers 1 - wg a'N^-1 a) and RMS of the geometric
    observations at the final state."""
    ncol = NPX + 2 * n
    cols = np.empty(ncol, np.int64)
    for p in range(NPX):
        cols[p] = p
    for i in range(n):
        cols[NPX + 2 * i] = NPX + NPI * i
        cols[NPX + 2 * i + 1] = NPX + NPI * i + 3
    q = np.empty((ncol, npar))  # rows: columns `cols` of N^-1
    cv = np.empty((ncol, npar))  # rows: columns `cols` of N^-1 M N^-1
    e = np.zeros(npar)
    mz = np.empty(npar)
    for c in range(ncol):
        e[cols[c]] = 1.0
        _chol_solve(lower, e, q[c], npar)
        e[cols[c]] = 0.0
        for p in range(npar):
            t = 0.0
            for r in range(npar):
                t += (mmat[p, r] if r >= p else mmat[r, p]) * q[c, r]
            mz[p] = t
        _chol_solve(lower, mz, cv[c], npar)
    for i in range(n):
        qxx = cv[NPX + 2 * i, cols[NPX + 2 * i]]
        qxy = cv[NPX + 2 * i, cols[NPX + 2 * i + 1]]
        qyy = cv[NPX + 2 * i + 1, cols[NPX + 2 * i + 1]]
        mean = 0.5 * (qxx + qyy)
        dif = math.sqrt(0.25 * (qxx - qyy) ** 2 + qxy * qxy)
        out[3 * i + 1] = math.sqrt(max(mean + dif, 0.0))
        out[3 * i + 2] = math.sqrt(max(mean - dif, 0.0))
    base = 3 * n + COV
    k = 0
    for p in range(NPX):
        for r in range(p, NPX):
            out[base + k] = cv[p, r]
            k += 1
    coef = np.empty(NPX)
    vtpv = 0.0
    red = 0.0
    vv = 0.0
    for i in range(n + 1):
        for c in range(2):
            col, v = _geo_row(i, c, x0, y0, cen, jac, state, dx, coef)
            aqa = 0.0
            for p in range(NPX):
                for r in range(NPX):
                    aqa += coef[p] * coef[r] * q[p, r]
            if col >= 0:
                qc = NPX + 2 * (i - 1) + c  # row of q holding column `col` of Q
                for p in range(NPX):
                    aqa += 2.0 * coef[p] * q[p, col]
                aqa += q[qc, col]
            red += 1.0 - wg * aqa
            vtpv += wg * v * v
            vv += v * v
    out[3 * n + GEO_VTPV] = vtpv
    out[3 * n + GEO_RED] = red
    out[3 * n + GEO_RMS] = math.sqrt(vv / (2 * (n + 1)))


@njit(cache=True, nogil=True, parallel=True)
def mpgc_batch(stack, x0, y0, cen, jac, state, dx, active, solve, out, status, iterations):
    """mpgc_point over the points with active[p] (parallel); iterations[p] accumulates."""
    for p in prange(x0.shape[0]):
        if active[p]:
            st, it = mpgc_point(stack, x0[p], y0[p], cen[p], jac[p], state[p], dx[p], solve, out[p])
            status[p] = st
            iterations[p] += it
