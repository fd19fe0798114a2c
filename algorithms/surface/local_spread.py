"""The local height spread of a point cloud: how far the surface around a point is from one height.

For a query point (x, y) (metres in a local frame that every caller shares) and a half-width R, the spread is
the standard deviation of the heights of the cloud's points within the square of cells around it:

    cells of size g = 2 R / 5 on the frame's grid (origin 0, so that tiles of one cloud agree), the query's cell
    and the 2 cells on each side (a square of 5 g = 2 R), s^2 = sum (h - mean)^2 / n over its n points.

It is computed from per-cell counts, sums and sums of squares (heights about a reference height, against
cancellation), box-summed over the 5 x 5 cells: O(n), with memory of the points' bounding box in cells. NaN
where the square holds fewer than MIN_POINTS points. A sloping plane has a spread too (its relief across the
square), which is part of what a matching template sees.

Used by the dense points' precision (dense/precision.py): a template straddling two surfaces measures a mixture
of them, an error that grows with their height difference and that LSM's error ellipse does not see."""

import numpy as np

from ..geodesy import metres_per_degree

#: fewest points of the square for a spread
MIN_POINTS = 5
#: cells on each side of the query's cell
REACH = 2


def local_metres(lon, lat, centre):
    """(x, y) metres east and north of `centre` (lon, lat) on the sphere of its radii: the frame the tiles of one
    cloud share."""
    east, north = metres_per_degree(centre[1])
    return (np.asarray(lon, float) - centre[0]) * east, (np.asarray(lat, float) - centre[1]) * north


def cell_size(radius):
    """g (m): the grid's cell for half-width `radius`."""
    return 2.0 * float(radius) / (2 * REACH + 1)


def reach_m(radius):
    """The farthest (m, along x or y) a point can lie from a query and enter its square: the margin a tile of the
    cloud needs around it."""
    return (REACH + 1) * cell_size(radius)


def local_spread(x, y, h, qx, qy, radius):
    """Per query point (qx, qy), the spread (module docstring) of the points (x, y, h) around it, half-width
    `radius` (m)."""
    qx, qy = np.asarray(qx, float), np.asarray(qy, float)
    out = np.full(qx.size, np.nan)
    x, y, h = (np.asarray(v, float) for v in (x, y, h))
    if x.size == 0 or qx.size == 0:
        return out
    g = cell_size(radius)
    ix, iy = np.floor(x / g).astype(np.int64), np.floor(y / g).astype(np.int64)
    x0, y0 = ix.min() - REACH, iy.min() - REACH
    shape = (int(iy.max() - y0 + REACH + 1), int(ix.max() - x0 + REACH + 1))
    flat = (iy - y0) * shape[1] + (ix - x0)
    dz = h - np.median(h)
    sums = [
        np.bincount(flat, weights=w, minlength=shape[0] * shape[1]).reshape(shape)
        for w in (np.ones_like(dz), dz, dz * dz)
    ]
    n, s, ss = (_box_sum(a, REACH) for a in sums)
    qi, qj = np.floor(qy / g).astype(np.int64) - y0, np.floor(qx / g).astype(np.int64) - x0
    inside = (qi >= 0) & (qi < shape[0]) & (qj >= 0) & (qj < shape[1])
    cnt = np.zeros(qx.size)
    cnt[inside] = n[qi[inside], qj[inside]]
    use = cnt >= MIN_POINTS
    mean = s[qi[use], qj[use]] / cnt[use]
    out[use] = np.sqrt(np.maximum(ss[qi[use], qj[use]] / cnt[use] - mean * mean, 0.0))
    return out


def _box_sum(a, k):
    """Sum of `a` over the (2k + 1)^2 cells around each cell (zero outside)."""
    c = np.pad(a, ((k + 1, k), (k + 1, k))).cumsum(axis=0).cumsum(axis=1)
    w = 2 * k + 1
    return c[w:, w:] - c[:-w, w:] - c[w:, :-w] + c[:-w, :-w]
