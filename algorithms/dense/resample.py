"""Epipolar images: an image resampled at the positions an EpipolarGrid gives its epipolar pixels.

Element [i, j] of the epipolar image is the image's Keys cubic convolution (interpolation.cubic) at
the grid's bilinear position of (u, v) = (u0 + j, v0 + i), read from one window of the image that
holds every node: memory follows the tile. NaN where the position has no 4 x 4 neighbourhood inside
the image, where a node is NaN (outside a model's domain) and where the image is nodata (NaN spreads
over the cubic's support)."""

import math

import numpy as np
from numba import njit

from ..interpolation import cubic
from ..matching.imagery import as_image


@njit(cache=True, nogil=True)
def resample_kernel(img, x0, y0, nodes, step, out):
    """out[i, j] = cubic(img, x - x0, y - y0) with (x, y) the bilinear position of epipolar pixel (i, j)
    between `nodes` (rows, cols, 2), `step` px apart; NaN where the 4 x 4 support leaves img."""
    rows, cols = img.shape
    na, nb = nodes.shape[0], nodes.shape[1]
    for i in range(out.shape[0]):
        a = min(i // step, na - 2)
        ta = (i - a * step) / step
        for j in range(out.shape[1]):
            b = min(j // step, nb - 2)
            tb = (j - b * step) / step
            w00, w01, w10, w11 = (1 - ta) * (1 - tb), (1 - ta) * tb, ta * (1 - tb), ta * tb
            x = (
                w00 * nodes[a, b, 0]
                + w01 * nodes[a, b + 1, 0]
                + w10 * nodes[a + 1, b, 0]
                + w11 * nodes[a + 1, b + 1, 0]
            ) - x0
            y = (
                w00 * nodes[a, b, 1]
                + w01 * nodes[a, b + 1, 1]
                + w10 * nodes[a + 1, b, 1]
                + w11 * nodes[a + 1, b + 1, 1]
            ) - y0
            if not (x == x and y == y):
                out[i, j] = np.nan
                continue
            c0 = math.floor(x - 0.5)
            r0 = math.floor(y - 0.5)
            if c0 < 1 or r0 < 1 or c0 + 2 > cols - 1 or r0 + 2 > rows - 1:
                out[i, j] = np.nan
                continue
            out[i, j] = cubic(img, x, y)[0]


def epipolar_image(image, nodes, step):
    """The epipolar image (float32, the grid's shape) of `image` (a path, an array or an Image-like,
    e.g. matching.imagery.Smoothed for the finer image of a pair) at grid nodes `nodes` (EpipolarGrid.p
    for image 1, .q for image 2)."""
    image = as_image(image)
    shape = ((nodes.shape[0] - 1) * step + 1, (nodes.shape[1] - 1) * step + 1)
    out = np.full(shape, np.nan, np.float32)
    finite = nodes[np.isfinite(nodes).all(axis=-1)]
    if finite.size == 0:
        return out
    xa, ya = (int(math.floor(v)) - 3 for v in finite.min(axis=0))
    xb, yb = (int(math.ceil(v)) + 3 for v in finite.max(axis=0))
    window, wx, wy = image.read(xa, ya, xb - xa, yb - ya)
    if window.size == 0:
        return out
    resample_kernel(window, float(wx), float(wy), np.ascontiguousarray(nodes, dtype=np.float64), int(step), out)
    return out
