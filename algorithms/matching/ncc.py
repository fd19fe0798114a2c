"""Normalised cross-correlation along a search path (quasi-epipolar segment) with an affine
window shape, so that rotations and 2:1 scale differences correlate. Coordinates are GDAL's
(pixel (i, j) has its centre at (j + 0.5, i + 0.5)); all samples are bilinear."""

import math

import numpy as np
from numba import njit

from ..interpolation import FAST, bilinear, bilinear_inside


@njit(cache=True, nogil=True, fastmath=FAST)
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
    nr, nc = img2.shape
    for c in range(px.shape[0]):
        # the window is affine: its samples lie inside the pixel-centre hull where its four corners do
        inside = nr >= 2 and nc >= 2
        for sk in (-half, half):
            for sl in (-half, half):
                xc = px[c] + a1 * sk + a2 * sl - 0.5
                yc = py[c] + a4 * sk + a5 * sl - 0.5
                inside = inside and xc >= 0.0 and yc >= 0.0 and xc <= nc - 1 and yc <= nr - 1
        if not (inside and vf > 0.0 and math.isfinite(vf)):
            rho[c] = np.nan
            continue
        sg = sgg = sfg = 0.0
        idx = 0
        for l in range(-half, half + 1):
            xl = px[c] + a2 * l
            yl = py[c] + a5 * l
            for k in range(-half, half + 1):
                g = bilinear_inside(img2, xl + a1 * k, yl + a4 * k)
                sg += g
                sgg += g * g
                sfg += f[idx] * g
                idx += 1
        # a masked (NaN) pixel in the window makes the sums NaN: no correlation there
        bad = not math.isfinite(sg)
        vg = sgg - sg * sg / n
        rho[c] = sfg / math.sqrt(vf * vg) if not bad and vg > 1e-12 * sgg else np.nan
