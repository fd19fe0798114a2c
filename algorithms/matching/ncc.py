"""Normalised cross-correlation along a search path (quasi-epipolar segment) with an affine
window shape, so that rotations and 2:1 scale differences correlate. Coordinates are GDAL's
(pixel (i, j) has its centre at (j + 0.5, i + 0.5)); all samples are bilinear."""

import math

import numpy as np
from numba import njit

from ..interpolation import bilinear


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
