"""Normalised cross-correlation along a search path (quasi-epipolar segment) with an affine
window shape, so that rotations and 2:1 scale differences correlate. Coordinates are GDAL's
(pixel (i, j) has its centre at (j + 0.5, i + 0.5)); all samples are bilinear."""
import math

import numpy as np
from numba import njit

from ..errors import InputError
from .lsm import bilinear


@njit(cache=True, nogil=True)
def ncc_path(img1, img2, x1, y1, half, px, py, a1, a2, a4, a5, rho):
    """rho[c] = correlation coefficient between the (2 half + 1)^2 template of img1 at (x1, y1)
    and img2 sampled at (px[c] + a1 k + a2 l, py[c] + a4 k + a5 l); NaN where a window leaves an
    image or has no texture."""
    nside = 2 * half + 1
    n = nside * nside
    f = np.empty(n)
    idx = 0
    for l in range(-half, half + 1):
        for k in range(-half, half + 1):
            f[idx] = bilinear(img1, x1 + k, y1 + l)
            idx += 1
    mf = f.mean()
    f -= mf
    vf = (f * f).sum()
    for c in range(px.shape[0]):
        sg = sgg = sfg = 0.0
        bad = not (vf > 0.0) or not math.isfinite(vf)
        idx = 0
        for l in range(-half, half + 1):
            if bad:
                break
            for k in range(-half, half + 1):
                g = bilinear(img2, px[c] + a1 * k + a2 * l, py[c] + a4 * k + a5 * l)
                if not math.isfinite(g):
                    bad = True
                    break
                sg += g
                sgg += g * g
                sfg += f[idx] * g
                idx += 1
        vg = sgg - sg * sg / n
        rho[c] = sfg / math.sqrt(vf * vg) if not bad and vg > 1e-12 * sgg else np.nan


@njit(cache=True, nogil=True)
def ncc_peak(rho):
    """(best index, sub-pixel offset t in candidate steps from a parabola through the peak and
    its neighbours, best rho, second-peak rho = highest other local maximum, -1 if none);
    best index -1 if all NaN."""
    best = -1
    for c in range(rho.shape[0]):
        if math.isfinite(rho[c]) and (best < 0 or rho[c] > rho[best]):
            best = c
    if best < 0:
        return -1, 0.0, np.nan, np.nan
    t = 0.0
    if 0 < best < rho.shape[0] - 1 and math.isfinite(rho[best - 1]) and math.isfinite(rho[best + 1]):
        den = rho[best - 1] - 2.0 * rho[best] + rho[best + 1]
        if den < 0.0:
            t = 0.5 * (rho[best - 1] - rho[best + 1]) / den
    second = -1.0
    for c in range(rho.shape[0]):
        if c == best or not math.isfinite(rho[c]) or abs(c - best) <= 1:
            continue
        left = rho[c - 1] if c > 0 else -np.inf
        right = rho[c + 1] if c < rho.shape[0] - 1 else -np.inf
        if not (left > rho[c]) and not (right > rho[c]) and rho[c] > second:
            second = rho[c]
    return best, t, rho[best], second


def ncc_search(img1, img2, x1, y1, path_x, path_y, template=19, affine=(1.0, 0.0, 0.0, 1.0)):
    """Best match of the template of img1 at (x1, y1) among the candidate centres (path_x, path_y)
    in img2 (equally spaced along a segment for the sub-pixel parabola to hold).
    Returns (x, y, rho, second_rho); x, y NaN where no candidate could be correlated."""
    if template < 3 or template % 2 == 0:
        raise InputError(f"the NCC template must be an odd number of at least 3 pixels, got {template}")
    px = np.ascontiguousarray(path_x, dtype=np.float64)
    py = np.ascontiguousarray(path_y, dtype=np.float64)
    if px.ndim != 1 or px.shape != py.shape or px.size == 0:
        raise InputError("path_x and path_y must be 1-D arrays of the same non-zero length")
    rho = np.empty(px.size)
    a1, a2, a4, a5 = (float(v) for v in affine)
    ncc_path(np.asarray(img1), np.asarray(img2), float(x1), float(y1), template // 2, px, py, a1, a2, a4, a5, rho)
    best, t, rbest, second = ncc_peak(rho)
    if best < 0:
        return np.nan, np.nan, np.nan, np.nan
    nxt = best + 1 if t >= 0 else best - 1
    nxt = min(max(nxt, 0), px.size - 1)
    frac = abs(t)
    return (px[best] + frac * (px[nxt] - px[best]), py[best] + frac * (py[nxt] - py[best]), rbest, second)
