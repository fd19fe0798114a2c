"""Least-squares matching (Heipke et al. 1992, section 2, Kornus et al. 2006, section 3.3).

Model: a template of image 1 centred at (x1, y1) (offsets k, l in px of image 1) is matched to
image 2 under an affine geometric transformation

    x = x2 + a1 k + a2 l,    y = y2 + a4 k + a5 l

and a linear radiometric one, f(k, l) = r0 + r1 g(x, y). The 8 parameters (x2, a1, a2, y2, a4, a5,
r0, r1) are estimated by Gauss-Newton. Image 2 is resampled bicubically (Keys, a = -0.5: half the
interpolation bias of bilinear and smooth convergence); the Jacobian uses the template gradients
(central differences) mapped through the current affine, (r1 gx, r1 gy) = A^-T (fk, fl), which
equals the image-2 gradient at the solution but keeps image-2 noise out of the Jacobian (with
image-2 gradients the noise biases positions towards half-pixel phases and the reported precision
came out 2x optimistic). The template is sampled bilinearly (exact pixel values at pixel centres).
Coordinates are GDAL's: array pixel (i, j) has its centre at (j + 0.5, i + 0.5).

Robust weighting (tukey > 0, GrowParams.robust): after the first, unweighted iteration each sample's
equation is weighted by Tukey's biweight w = (1 - (v / (c s))^2)^2 (0 for |v| >= c s) of its residual v
against the weighted residual RMS s of the previous iteration, c = `tukey` (params.TUKEY_C: 95 % efficiency for
Gaussian residuals); the weights are updated for REWEIGHTINGS iterations and then kept, so the iteration
converges. Samples of another surface inside the template (a forest or a building beside a field) then
stop pulling the match (Huber 1981, ch. 7; as MPGC, mpgc.py). The first iteration is unweighted, so the
weights help where the other surface is a minority of the template (a template sliding onto a field's edge);
where it covers a quarter or more, the first step already lands between the two and the weights keep it
there (tests/algorithms/matching/test_lsm.py). tukey = 0: plain least squares.

Precision: sigma0^2 = v'Pv / (sum w - 8) a posteriori (sum w = n unweighted), covariance of (x2, y2) =
sigma0^2 times the (x2, y2) block of N^-1; `semi_major` / `semi_minor` are the square roots of its
eigenvalues (1-sigma error ellipse, px of image 2).
"""

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..errors import InputError
from ..interpolation import FAST, bilinear, cubic
from .params import LsmParams
from .records import PAIR_DTYPE

#: field order of the `out` vector that lsm_point fills
LSM_FIELDS = ("x2", "y2", "rho", "semi_major", "semi_minor", "shift", "iterations", "a1", "a2", "a4", "a5", "r0", "r1")
LSM_OUT = len(LSM_FIELDS)

#: lsm_point status codes
OK, OUTSIDE, SINGULAR, NOT_CONVERGED = 0, 1, 2, 3

_NPAR = 8
#: iterations that re-weight (the first ones after the unweighted one); later ones keep the weights
REWEIGHTINGS = 3


@njit(cache=True, nogil=True)
def _inside_grad(nrows, ncols, x, y):
    """True where bilinear value and gradient sampling at (x, y) stay inside the image
    (needs one more pixel on each side for the central differences)."""
    c = x - 0.5
    r = y - 0.5
    return c >= 1.0 and r >= 1.0 and c < ncols - 2.0 and r < nrows - 2.0


@njit(cache=True, nogil=True)
def _cholesky(n, npar):
    """In-place Cholesky (lower) of the upper-filled npar x npar matrix n; False if singular."""
    for j in range(npar):
        s = n[j, j]
        for k in range(j):
            s -= n[j, k] * n[j, k]
        # relative pivot test: flat texture gives exactly or nearly zero pivots
        if not (s > 1e-10 * abs(n[j, j]) and s > 1e-300):
            return False
        d = math.sqrt(s)
        n[j, j] = d
        for i in range(j + 1, npar):
            s = n[j, i]
            for k in range(j):
                s -= n[i, k] * n[j, k]
            n[i, j] = s / d
    return True


@njit(cache=True, nogil=True)
def _chol_solve(lower, b, x, npar):
    """Solve L L' x = b with the lower factor from _cholesky."""
    for i in range(npar):
        s = b[i]
        for k in range(i):
            s -= lower[i, k] * x[k]
        x[i] = s / lower[i, i]
    for i in range(npar - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, npar):
            s -= lower[k, i] * x[k]
        x[i] = s / lower[i, i]


@njit(cache=True, nogil=True)
def _window_inside(nrows, ncols, x2, y2, a1, a2, a4, a5, half):
    for sk in (-1.0, 1.0):
        for sl in (-1.0, 1.0):
            k = sk * half
            l = sl * half
            if not _inside_grad(nrows, ncols, x2 + a1 * k + a2 * l, y2 + a4 * k + a5 * l):
                return False
    return True


@njit(cache=True, nogil=True)
def template(img, x, y, half, f, fk, fl):
    """Template of (2 half + 1)^2 samples at integer offsets (k, l) from (x, y), row-major, sampled
    bilinearly (exact pixel values at pixel centres), and its central-difference gradients (one-
    sided at the image border, where the extra ring falls outside). False where the template leaves
    the image."""
    nr, nc = img.shape
    if not (x - half >= 0.5 and y - half >= 0.5 and x + half <= nc - 0.5 and y + half <= nr - 0.5):
        return False
    nside = 2 * half + 1
    edge = 0
    if x - half - 1 >= 0.5 and y - half - 1 >= 0.5 and x + half + 1 <= nc - 0.5 and y + half + 1 <= nr - 0.5:
        edge = 1
    tb = np.empty((nside + 2, nside + 2))
    for l in range(-half - 1, half + 2):
        for k in range(-half - 1, half + 2):
            kk = min(max(k, -half - edge), half + edge)
            ll = min(max(l, -half - edge), half + edge)
            tb[l + half + 1, k + half + 1] = bilinear(img, x + kk, y + ll)
    idx = 0
    for l in range(1, nside + 1):
        for k in range(1, nside + 1):
            f[idx] = tb[l, k]
            fk[idx] = 0.5 * (tb[l, k + 1] - tb[l, k - 1])
            fl[idx] = 0.5 * (tb[l + 1, k] - tb[l - 1, k])
            idx += 1
    return True


class Start(NamedTuple):
    """LSM's initial values in image 2: the position (x2, y2) and the affine (a1, a2, a4, a5) (module docstring)."""

    x2: float
    y2: float
    a1: float
    a2: float
    a4: float
    a5: float


class Solver(NamedTuple):
    """LSM's solution settings: template half-size (px), largest number of iterations, convergence (px: the
    position update below which it stops) and Tukey's constant of the robust weighting (0: off)."""

    half: int
    max_iter: int
    conv: float
    tukey: float = 0.0


def solver(params: LsmParams, half: int | None = None) -> Solver:
    """The Solver of `params` (its template; `half`: another half-size, the wide template's)."""
    return Solver(
        params.template // 2 if half is None else half, params.max_iterations, params.convergence, params.tukey
    )


@njit(cache=True, nogil=True, fastmath=FAST)
def lsm_point(img1, img2, x1, y1, start, solve, out):
    """Match the template of image 1 at (x1, y1) in image 2 from the Start `start` with the Solver `solve`; see
    the module docstring. Fills out (float64, LSM_OUT, order LSM_FIELDS) and returns the status: 0 ok, 1 window
    leaves image 1 or 2, 2 singular normal equations (flat texture), 3 not converged within max_iter (out holds
    the last state)."""
    x2, y2, a1, a2, a4, a5 = start
    half, max_iter, conv, tukey = solve
    for i in range(out.shape[0]):
        out[i] = np.nan
    out[6] = 0.0
    nr2, nc2 = img2.shape
    x2_0 = x2
    y2_0 = y2
    nside = 2 * half + 1
    nsamp = nside * nside
    f = np.empty(nsamp)
    fk = np.empty(nsamp)
    fl = np.empty(nsamp)
    if not template(img1, x1, y1, half, f, fk, fl):
        return OUTSIDE
    sf = 0.0
    sff = 0.0
    for idx in range(nsamp):
        sf += f[idx]
        sff += f[idx] * f[idx]
    r0 = 0.0
    r1 = 1.0
    nmat = np.empty((_NPAR, _NPAR))
    b = np.empty(_NPAR)
    dx = np.empty(_NPAR)
    converged = False
    it = 0
    sg = sgg = sfg = 0.0
    sll = 0.0
    skap = 0.0
    w = np.ones(nsamp)
    sw = float(nsamp)
    cs = 0.0
    while it < max_iter:
        if not (math.isfinite(x2) and math.isfinite(y2)) or not _window_inside(nr2, nc2, x2, y2, a1, a2, a4, a5, half):
            out[6] = it
            return OUTSIDE
        det = a1 * a5 - a2 * a4
        if not abs(det) > 1e-6:
            out[6] = it
            return SINGULAR
        ia11 = a5 / det
        ia12 = -a2 / det
        ia21 = -a4 / det
        ia22 = a1 / det
        nmat[:, :] = 0.0
        b[:] = 0.0
        sg = sgg = sfg = 0.0
        sll = 0.0
        skap = 0.0
        sw = 0.0
        reweight = cs > 0.0 and 0 < it <= REWEIGHTINGS
        idx = 0
        for l in range(-half, half + 1):
            # Jacobian row (gx, gx k, gx l, gy, gy k, gy l, 1, g) with (gx, gy) = r1 grad g at the
            # sample, from the template gradients (f = r0 + r1 g o T): (r1 gx, r1 gy) = A^-T (fk, fl).
            # Template gradients keep the noise of image 2 out of the Jacobian, which otherwise biases
            # the position towards half-pixel phases. The products with l are constant along a
            # template row: sums over k in moments of k first, then folded in with l below. Each
            # equation carries its robust weight (1 without); rg, rgg are unweighted (the correlation).
            xx0 = xx1 = xx2 = xy0 = xy1 = xy2 = yy0 = yy1 = yy2 = 0.0
            x0 = x1s = y0 = y1s = xg0 = xg1 = yg0 = yg1 = 0.0
            rg = rgg = rgw = rggw = 0.0
            bx0 = bx1 = by0 = by1 = bo = bgo = 0.0
            ya = y2 + a5 * l
            xa = x2 + a2 * l
            for k in range(-half, half + 1):
                g, kap = cubic(img2, xa + a1 * k, ya + a4 * k)
                fv = f[idx]
                obs = fv - (r0 + r1 * g)
                if reweight:
                    u = obs / cs
                    w[idx] = (1.0 - u * u) ** 2 if abs(u) < 1.0 else 0.0
                wi = w[idx]
                gx = ia11 * fk[idx] + ia21 * fl[idx]
                gy = ia12 * fk[idx] + ia22 * fl[idx]
                wx = wi * gx
                wy = wi * gy
                wg = wi * g
                fk_ = float(k)
                t = wx * gx
                xx0 += t
                xx1 += t * fk_
                xx2 += t * fk_ * fk_
                t = wx * gy
                xy0 += t
                xy1 += t * fk_
                xy2 += t * fk_ * fk_
                t = wy * gy
                yy0 += t
                yy1 += t * fk_
                yy2 += t * fk_ * fk_
                x0 += wx
                x1s += wx * fk_
                y0 += wy
                y1s += wy * fk_
                t = wx * g
                xg0 += t
                xg1 += t * fk_
                t = wy * g
                yg0 += t
                yg1 += t * fk_
                rg += g
                rgg += g * g
                rgw += wg
                rggw += wg * g
                t = wx * obs
                bx0 += t
                bx1 += t * fk_
                t = wy * obs
                by0 += t
                by1 += t * fk_
                bo += wi * obs
                bgo += wg * obs
                sll += wi * obs * obs
                sw += wi
                sfg += fv * g
                skap += kap
                idx += 1
            fl_ = float(l)
            ll = fl_ * fl_
            nmat[0, 0] += xx0
            nmat[0, 1] += xx1
            nmat[0, 2] += fl_ * xx0
            nmat[1, 1] += xx2
            nmat[1, 2] += fl_ * xx1
            nmat[2, 2] += ll * xx0
            nmat[0, 3] += xy0
            nmat[0, 4] += xy1
            nmat[0, 5] += fl_ * xy0
            nmat[1, 3] += xy1
            nmat[1, 4] += xy2
            nmat[1, 5] += fl_ * xy1
            nmat[2, 3] += fl_ * xy0
            nmat[2, 4] += fl_ * xy1
            nmat[2, 5] += ll * xy0
            nmat[3, 3] += yy0
            nmat[3, 4] += yy1
            nmat[3, 5] += fl_ * yy0
            nmat[4, 4] += yy2
            nmat[4, 5] += fl_ * yy1
            nmat[5, 5] += ll * yy0
            nmat[0, 6] += x0
            nmat[1, 6] += x1s
            nmat[2, 6] += fl_ * x0
            nmat[3, 6] += y0
            nmat[4, 6] += y1s
            nmat[5, 6] += fl_ * y0
            nmat[0, 7] += xg0
            nmat[1, 7] += xg1
            nmat[2, 7] += fl_ * xg0
            nmat[3, 7] += yg0
            nmat[4, 7] += yg1
            nmat[5, 7] += fl_ * yg0
            nmat[6, 7] += rgw
            nmat[7, 7] += rggw
            b[0] += bx0
            b[1] += bx1
            b[2] += fl_ * bx0
            b[3] += by0
            b[4] += by1
            b[5] += fl_ * by0
            b[6] += bo
            b[7] += bgo
            sg += rg
            sgg += rgg
        nmat[6, 6] = sw
        # only the upper triangle is filled: _cholesky reads n[j, i] for i > j
        if not _cholesky(nmat, _NPAR):
            out[6] = it
            return SINGULAR
        _chol_solve(nmat, b, dx, _NPAR)
        if not math.isfinite(dx[0] + dx[1] + dx[2] + dx[3] + dx[4] + dx[5] + dx[6] + dx[7]):
            out[6] = it
            return SINGULAR
        x2 += dx[0]
        a1 += dx[1]
        a2 += dx[2]
        y2 += dx[3]
        a4 += dx[4]
        a5 += dx[5]
        r0 += dx[6]
        r1 += dx[7]
        it += 1
        if tukey > 0.0:
            cs = tukey * math.sqrt(sll / sw) if sw > 0.0 else 0.0
        if math.sqrt(dx[0] * dx[0] + dx[3] * dx[3]) < conv:
            converged = True
            break
    # precision from the last normal equations: v'v = l'l - dx'b (linearised post-fit residuals)
    vtv = sll
    for p in range(_NPAR):
        vtv -= dx[p] * b[p]
    if vtv < 0.0:
        vtv = 0.0
    s02 = vtv / max(sw - _NPAR, 1.0)
    # The residuals see image-2 noise after resampling (variance scaled by kappa < 1) while the
    # position error feels it at full strength, repeated on every template sample that falls in
    # the same image-2 pixel when image 2 is coarser (|det A| < 1). Assuming equal white noise in
    # both images (in grey values of each), scale sigma0^2 accordingly.
    r1sq = r1 * r1
    det = abs(a1 * a5 - a2 * a4)
    rep = 1.0 / det if 0.0 < det < 1.0 else 1.0
    s02 *= (1.0 + r1sq * rep) / (1.0 + r1sq * skap / nsamp)
    e = np.zeros(_NPAR)
    z = np.empty(_NPAR)
    e[0] = 1.0
    _chol_solve(nmat, e, z, _NPAR)
    qxx = z[0]
    qxy = z[3]
    e[0] = 0.0
    e[3] = 1.0
    _chol_solve(nmat, e, z, _NPAR)
    qyy = z[3]
    mean = 0.5 * (qxx + qyy)
    dif = math.sqrt(0.25 * (qxx - qyy) ** 2 + qxy * qxy)
    lam1 = mean + dif
    lam2 = max(mean - dif, 0.0)
    n = float(nsamp)
    vf = sff - sf * sf / n
    vg = sgg - sg * sg / n
    cfg = sfg - sf * sg / n
    rho = cfg / math.sqrt(vf * vg) if vf > 0.0 and vg > 0.0 else 0.0
    out[0] = x2
    out[1] = y2
    out[2] = rho
    out[3] = math.sqrt(s02 * lam1)
    out[4] = math.sqrt(s02 * lam2)
    out[5] = math.sqrt((x2 - x2_0) ** 2 + (y2 - y2_0) ** 2)
    out[6] = it
    out[7] = a1
    out[8] = a2
    out[9] = a4
    out[10] = a5
    out[11] = r0
    out[12] = r1
    return OK if converged else NOT_CONVERGED


@njit(cache=True, nogil=True, parallel=True)
def _match_kernel(img1, img2, x1, y1, x2, y2, aff, solve, out, status):
    for p in prange(x1.shape[0]):
        start = Start(x2[p], y2[p], aff[p, 0], aff[p, 1], aff[p, 2], aff[p, 3])
        status[p] = lsm_point(img1, img2, x1[p], y1[p], start, solve, out[p])


def _as_image(img, name):
    img = np.asarray(img)
    if img.ndim != 2 or img.shape[0] < 4 or img.shape[1] < 4:
        raise InputError(f"{name} must be a 2-D image of at least 4 x 4 pixels, got shape {img.shape}")
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    return np.ascontiguousarray(img)


def _affine_array(affine, n):
    if affine is None:
        aff = np.empty((n, 4))
        aff[:] = (1.0, 0.0, 0.0, 1.0)
        return aff
    aff = np.asarray(affine, dtype=np.float64)
    if aff.shape == (4,):
        return np.tile(aff, (n, 1))
    if aff.shape != (n, 4):
        raise InputError(f"affine must be (a1, a2, a4, a5) or an array of shape ({n}, 4), got {aff.shape}")
    # one array type for the kernel, whatever the caller's (a read-only array would compile it again)
    return np.require(aff, np.float64, ["C_CONTIGUOUS", "WRITEABLE"])


def match_points(img1, img2, x1, y1, x2, y2, affine=None, params=None):
    """Least-squares match of many points (parallel over points).

    x1, y1: template centres in image 1; x2, y2: initial positions in image 2 (GDAL coordinates of
    each array); affine: initial (a1, a2, a4, a5), one 4-tuple for all or an (n, 4) array
    (default identity); params: LsmParams (template size, iterations, convergence).
    Returns (records, status): a PAIR_DTYPE array (x1, y1 as given, the matched x2, y2 and quality;
    NaN where no result) and the int8 status per point (0 ok, 1 outside, 2 singular,
    3 not converged). Use `accepted` for the acceptance criteria."""
    params = (params or LsmParams()).check()
    img1 = _as_image(img1, "image 1")
    img2 = _as_image(img2, "image 2")
    x1, y1, x2, y2 = (np.ascontiguousarray(np.atleast_1d(np.asarray(v, dtype=np.float64))) for v in (x1, y1, x2, y2))
    n = x1.size
    if not (y1.size == x2.size == y2.size == n):
        raise InputError("x1, y1, x2, y2 must have the same length")
    aff = _affine_array(affine, n)
    out = np.empty((n, LSM_OUT))
    status = np.empty(n, dtype=np.int8)
    _match_kernel(img1, img2, x1, y1, x2, y2, aff, solver(params), out, status)
    return to_records(x1, y1, out), status


def to_records(x1, y1, out):
    """PAIR_DTYPE records (seed -1) from template centres and lsm_point output rows."""
    rec = np.zeros(len(out), dtype=PAIR_DTYPE)
    rec["x1"] = x1
    rec["y1"] = y1
    for i, name in enumerate(LSM_FIELDS):
        rec[name] = out[:, i]
    rec["seed"] = -1
    return rec


def accepted(records, status, params=None):
    """Boolean mask of the points meeting the acceptance criteria:
    status 0, rho > rho_min, semi-major axis < max_ellipse, shift < max_shift,
    iterations < max_iterations."""
    params = params or LsmParams()
    with np.errstate(invalid="ignore"):
        return (
            (np.asarray(status) == OK)
            & (records["rho"] > params.rho_min)
            & (records["semi_major"] < params.max_ellipse)
            & (records["shift"] < params.max_shift)
            & (records["iterations"] < params.max_iterations)
        )


@njit(cache=True, nogil=True)
def template_units(wide_half: int, half: int) -> float:
    """The factor that reports the wide window's error ellipse in the template's units (match_accepted): the
    wide window's width over the template's, for half-sizes `wide_half` and `half`."""
    return (2 * wide_half + 1) / (2 * half + 1)


def match_accepted(img1, img2, x1, y1, x2, y2, affine=None, params=None):
    """match_points and `accepted`, with the points that fail inside the images matched again with
    the wider window `params.widest` (GrowParams.wide_template) from the same initial values; with
    GrowParams.wide_beyond_shift off, not those the template moved beyond max_shift.
    Returns (records, accepted mask).

    A position the wide window placed reports its error ellipse in the template's units: the semi-axes
    times widest / template (template_units). The white-noise ellipse shrinks as 1 / width, but the wide
    window serves the weak textures the template cannot match, where the error does not shrink so (the start is far off,
    the residuals are the texture's own, not white): the simulated triplet's low-texture DSM cells, which
    the wide window serves, were 1.3-1.8x optimistic where the open fields' were calibrated
    (studies/README.md#dense_cell_precision), and region growing's wide-window points erred 3x their
    ellipses (docs/validation.md#region-growing-wide-template).
    In the template's units one precision model (dense/precision.py) serves both windows' positions. The
    acceptance tests the ellipse the window measured."""
    params = params or LsmParams()
    rec, status = match_points(img1, img2, x1, y1, x2, y2, affine, params)
    ok = accepted(rec, status, params)
    retry = ~ok & (status != OUTSIDE)
    if params.widest > params.template and not params.wide_beyond_shift:
        retry &= ~(rec["shift"] >= params.max_shift)
    again = np.flatnonzero(retry)
    if params.widest > params.template and again.size:
        wide = replace(params, template=params.widest, wide_template=0)  # only GrowParams has a wider one
        x2, y2 = (np.broadcast_to(np.asarray(v, float), rec.shape)[again] for v in (x2, y2))
        rec_w, status_w = match_points(
            img1, img2, rec["x1"][again], rec["y1"][again], x2, y2, _affine_array(affine, len(rec))[again], wide
        )
        good = accepted(rec_w, status_w, wide)
        for axis in ("semi_major", "semi_minor"):
            rec_w[axis] *= np.float32(template_units(params.widest // 2, params.template // 2))
        rec[again[good]] = rec_w[good]
        ok[again[good]] = True
    return rec, ok
