"""Interpolation of an image at GDAL positions, shared by matching and orthorectification.

Coordinates are GDAL's: array pixel (i, j) has its centre at (x, y) = (j + 0.5, i + 0.5).
- `bilinear`: exact pixel values at pixel centres, NaN outside the hull of the pixel centres.
- `cubic`: Keys' cubic convolution with a = -0.5 (R. G. Keys, "Cubic convolution interpolation for
  digital image processing", IEEE Trans. ASSP 29(6), 1981), which interpolates the pixel values,
  with the variance factor of white noise resampled by it.
"""

import math

import numpy as np
from numba import njit

#: numba's fast-math flags for the interpolation and matching kernels: reassociation (the sums vectorise) and fused
#: multiply-add, never the finite-math assumptions (the kernels test NaN and infinity)
FAST = {"reassoc", "contract", "nsz", "arcp"}


@njit(cache=True, nogil=True, fastmath=FAST)
def bilinear(img, x, y):
    """Bilinear grey value of img at GDAL position (x, y); NaN outside the pixel-centre hull."""
    nrows, ncols = img.shape
    c = x - 0.5
    r = y - 0.5
    if not (c >= 0.0 and r >= 0.0 and c <= ncols - 1 and r <= nrows - 1):
        return np.nan
    j0 = int(math.floor(c))
    i0 = int(math.floor(r))
    if j0 > ncols - 2:
        j0 = ncols - 2
    if i0 > nrows - 2:
        i0 = nrows - 2
    if j0 < 0:  # single-column / single-row images
        j0 = 0
    if i0 < 0:
        i0 = 0
    fx = c - j0
    fy = r - i0
    j1 = min(j0 + 1, ncols - 1)
    i1 = min(i0 + 1, nrows - 1)
    top = img[i0, j0] * (1.0 - fx) + img[i0, j1] * fx
    bottom = img[i1, j0] * (1.0 - fx) + img[i1, j1] * fx
    return top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True, fastmath=FAST)
def bilinear_inside(img, x, y):
    """`bilinear` where the caller guarantees that (x, y) lies inside the pixel-centre hull of an image of at
    least 2 x 2 pixels (no test, for the inner loops of correlation)."""
    c = x - 0.5
    r = y - 0.5
    j0 = min(int(c), img.shape[1] - 2)
    i0 = min(int(r), img.shape[0] - 2)
    fx = c - j0
    fy = r - i0
    top = img[i0, j0] * (1.0 - fx) + img[i0, j0 + 1] * fx
    bottom = img[i0 + 1, j0] * (1.0 - fx) + img[i0 + 1, j0 + 1] * fx
    return top * (1.0 - fy) + bottom * fy


@njit(cache=True, nogil=True)
def keys_weights(t):
    """Keys cubic convolution (a = -0.5) weights for fraction t in [0, 1) at the nodes -1, 0, 1, 2."""
    t2 = t * t
    t3 = t2 * t
    w0 = -0.5 * t3 + t2 - 0.5 * t
    w1 = 1.5 * t3 - 2.5 * t2 + 1.0
    w2 = -1.5 * t3 + 2.0 * t2 + 0.5 * t
    w3 = 0.5 * t3 - 0.5 * t2
    return w0, w1, w2, w3


@njit(cache=True, nogil=True, fastmath=FAST)
def cubic(img, x, y):
    """(g, kappa): bicubic (Keys, a = -0.5) grey value at (x, y), which interpolates the pixel
    values, and kappa = the sum of the squared weights (the factor by which resampling scales the
    variance of white noise). The caller guarantees that the 4 x 4 neighbourhood, rows and columns
    floor(. - 0.5) - 1 ... + 2, lies inside the image."""
    c = x - 0.5
    r = y - 0.5
    j0 = int(math.floor(c))
    i0 = int(math.floor(r))
    wx0, wx1, wx2, wx3 = keys_weights(c - j0)
    wy0, wy1, wy2, wy3 = keys_weights(r - i0)
    g = (
        wy0
        * (wx0 * img[i0 - 1, j0 - 1] + wx1 * img[i0 - 1, j0] + wx2 * img[i0 - 1, j0 + 1] + wx3 * img[i0 - 1, j0 + 2])
        + wy1 * (wx0 * img[i0, j0 - 1] + wx1 * img[i0, j0] + wx2 * img[i0, j0 + 1] + wx3 * img[i0, j0 + 2])
        + wy2
        * (wx0 * img[i0 + 1, j0 - 1] + wx1 * img[i0 + 1, j0] + wx2 * img[i0 + 1, j0 + 1] + wx3 * img[i0 + 1, j0 + 2])
        + wy3
        * (wx0 * img[i0 + 2, j0 - 1] + wx1 * img[i0 + 2, j0] + wx2 * img[i0 + 2, j0 + 1] + wx3 * img[i0 + 2, j0 + 2])
    )
    kappa = (wx0 * wx0 + wx1 * wx1 + wx2 * wx2 + wx3 * wx3) * (wy0 * wy0 + wy1 * wy1 + wy2 * wy2 + wy3 * wy3)
    return g, kappa
