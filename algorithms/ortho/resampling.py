"""Resampling of the image at the image points of output cells: bilinear, or bicubic convolution (Keys
1981, a = -0.5), the kernels of algorithms/interpolation.py (GDAL's pixel convention).

The image is read by windows: `padded_window` reads the pixels a tile needs plus a margin of PAD pixels
and replicates the border pixels where the margin passes the image edge, so both kernels run without
bounds tests. A cell whose image point lies outside the image (col not in [0, cols] or row not in
[0, rows]) or is NaN gets nodata."""

import math

import numpy as np
from numba import njit

from ..interpolation import bilinear, cubic

BILINEAR, BICUBIC = 0, 1
METHODS = {"bilinear": BILINEAR, "bicubic": BICUBIC}
#: window margin (px): the 4 x 4 bicubic neighbourhood of a point on the image edge
PAD = 2


@njit(cache=True, nogil=True)
def resample_kernel(window, col0, row0, cols, rows, col, row, method, out, valid):
    """out[b, p] = image band b at (col[p], row[p]) from window (bands, h, w), whose pixel (0, 0) has its
    top-left corner at image (col0, row0); valid[p] = whether the point lies in the image."""
    for p in range(col.size):
        c = col[p]
        r = row[p]
        valid[p] = c >= 0.0 and r >= 0.0 and c <= cols and r <= rows
        if not valid[p]:
            continue
        x = c - col0
        y = r - row0
        for b in range(window.shape[0]):
            if method == BICUBIC:
                out[b, p] = cubic(window[b], x, y)[0]
            else:
                out[b, p] = bilinear(window[b], x, y)


def window_bounds(col, row, size):
    """(col0, row0, col1, row1): integer pixel range covering the finite image points inside the image of
    `size` (cols, rows) plus PAD; None when no point falls inside."""
    cols, rows = size
    inside = np.isfinite(col) & np.isfinite(row) & (col >= 0) & (row >= 0) & (col <= cols) & (row <= rows)
    if not inside.any():
        return None
    c, r = col[inside], row[inside]
    return (
        math.floor(c.min()) - PAD,
        math.floor(r.min()) - PAD,
        math.floor(c.max()) + PAD + 1,
        math.floor(r.max()) + PAD + 1,
    )


def padded_window(dataset, bounds):
    """float32 array (bands, rows, cols) of image pixels [col0, col1) x [row0, row1), edge-replicated
    beyond the image."""
    col0, row0, col1, row1 = bounds
    xs, ys = dataset.RasterXSize, dataset.RasterYSize
    a0, b0 = min(max(col0, 0), xs - 1), min(max(row0, 0), ys - 1)
    a1, b1 = max(min(col1, xs), a0 + 1), max(min(row1, ys), b0 + 1)
    data = dataset.ReadAsArray(a0, b0, a1 - a0, b1 - b0).astype(np.float32)
    data = data.reshape((-1,) + data.shape[-2:])
    pad = ((0, 0), (max(b0 - row0, 0), max(row1 - b1, 0)), (max(a0 - col0, 0), max(col1 - a1, 0)))
    return np.pad(data, pad, mode="edge") if any(p != (0, 0) for p in pad) else data


def resample(dataset, col, row, method):
    """(values (bands, n) float32, valid (n,) bool) of `dataset` at image points col, row (1-D)."""
    col = np.ascontiguousarray(col, np.float64)
    row = np.ascontiguousarray(row, np.float64)
    out = np.zeros((dataset.RasterCount, col.size), np.float32)
    valid = np.zeros(col.size, np.bool_)
    bounds = window_bounds(col, row, (dataset.RasterXSize, dataset.RasterYSize))
    if bounds is None:
        return out, valid
    window = padded_window(dataset, bounds)
    resample_kernel(
        window,
        float(bounds[0]),
        float(bounds[1]),
        float(dataset.RasterXSize),
        float(dataset.RasterYSize),
        col,
        row,
        METHODS[method],
        out,
        valid,
    )
    return out, valid
