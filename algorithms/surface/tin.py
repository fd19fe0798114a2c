"""Delaunay TIN of a point cloud (delaunay.py's sweep-hull, qhull through scipy.spatial as the fallback),
breaklines as conforming constraints, the blunder filter against the TIN neighbours and the
longest edge of each triangle (for the gap rule).

Blunder residuals are taken against the least-squares plane through a point's TIN neighbours rather
than their median height: on slopes the median of an uneven neighbourhood departs from the point by
slope x offset, which flagged 1 % of clean points of a hilly test surface (0.3 m noise) at k = 4,
the plane 0.06 %.

Breaklines: scipy's Delaunay has no constraints, so the lines are densified into vertices and every
sub-segment is split until its diametral circle holds no other point (conforming Delaunay: a segment
with an empty diametral circle is a Gabriel edge, hence an edge of every Delaunay triangulation of
the points, so no triangle crosses the line). Mass points closer than `min_length` / 2 to a
breakline, which would force endless splits, give way to the line and are dropped (counted)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numba import njit
from scipy.spatial import Delaunay, QhullError, cKDTree

from .. import histogram
from ..errors import InputError
from ..stats import NMAD_SCALE
from .delaunay import seed, triangulate

#: smallest robust sigma of the blunder filter (m), below the height precision of any satellite point
#: cloud: a noise-free smooth surface loses no points to its curvature
MIN_SIGMA = 0.05


def flat_points(x, y):
    """Why the points (x, y) span no area, in words ('are all at one position ...', 'all lie on one line
    ...'), or None where three of them are not on one line (delaunay.seed's orientation tolerance)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if np.ptp(x) == 0.0 and np.ptp(y) == 0.0:
        return f"are all at one position (x {x[0]:.3f}, y {y[0]:.3f})"
    if seed(x - np.mean(x), y - np.mean(y))[2] < 0:
        ends = np.argmin(x + y), np.argmax(x + y)
        return (
            f"all lie on one line (from x {x[ends[0]]:.3f}, y {y[ends[0]]:.3f} to x {x[ends[1]]:.3f}, "
            f"y {y[ends[1]]:.3f})"
        )
    return None


def delaunay(x, y):
    """Delaunay triangulation of (x, y) (shifted to their mean for precision): the numba sweep-hull of
    delaunay.py, or scipy's (qhull) where that fails its validity check; InputError for fewer than 3 points,
    points at one position or on one line (flat_points), or points qhull cannot triangulate either. Both
    results have `simplices` and `vertex_neighbor_vertices`."""
    if len(x) < 3:
        raise InputError(
            f"a TIN needs at least 3 points, the point cloud has {len(x)}: check the input "
            "(an empty or almost empty point cloud, or every point filtered out)"
        )
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise InputError(
            f"{np.sum(~(np.isfinite(x) & np.isfinite(y)))} of the {len(x)} points of the TIN are not "
            "finite: leave them out"
        )
    tin = triangulate(x - np.mean(x), y - np.mean(y))
    if tin is not None:
        return tin
    flat = flat_points(x, y)
    if flat is not None:
        raise InputError(
            f"the {len(x)} points of the point cloud {flat}: a TIN needs at least 3 points that are "
            "not on one line; check the point cloud (duplicated points, or coordinates lost or "
            "rounded in an export?)"
        )
    x, y = x - np.mean(x), y - np.mean(y)
    try:
        return Delaunay(np.column_stack([x, y]))
    except (QhullError, ValueError) as exc:
        raise InputError(
            f"the {len(x)} points cannot be triangulated, not even by qhull: they are nearly all at "
            "one position or on one line; check the point cloud"
        ) from exc


def longest_edge(x, y, triangles):
    """Length of the longest edge of each triangle (m, 3 vertex indices)."""
    px, py = x[triangles], y[triangles]
    d = [np.hypot(px[:, a] - px[:, b], py[:, a] - py[:, b]) for a, b in ((0, 1), (1, 2), (2, 0))]
    return np.maximum(np.maximum(d[0], d[1]), d[2])


def densify(line, spacing):
    """Vertices of a 3-D polyline (n, 3) with extra vertices (linear in x, y, z) so that no segment is
    longer than `spacing`."""
    out = [line[:1]]
    for a, b in zip(line[:-1], line[1:]):
        k = max(int(np.ceil(np.hypot(*(b[:2] - a[:2])) / spacing)), 1)
        out.append(a + (b - a) * (np.arange(1, k + 1)[:, None] / k))
    return np.concatenate(out)


def conform_breaklines(lines, x, y, spacing, min_length, max_rounds=30):
    """Breakline vertices and segments for a conforming Delaunay TIN with the mass points (x, y).

    Returns (vertices (b, 3), segments (s, 2) indices into vertices, keep mask of the mass points).
    Segments are split at their midpoints while another point lies inside their diametral circle;
    at `min_length` the encroaching mass points are dropped instead."""
    keep = np.ones(len(x), bool)
    vertices, segments = [], []
    for line in lines:
        line = densify(np.asarray(line, float), spacing)
        start = sum(len(v) for v in vertices)
        vertices.append(line)
        segments.append(start + np.column_stack([np.arange(len(line) - 1), np.arange(1, len(line))]))
    if not vertices:
        return np.zeros((0, 3)), np.zeros((0, 2), np.int64), keep
    vertices, segments = np.concatenate(vertices), np.concatenate(segments)
    for _ in range(max_rounds):
        mass = np.flatnonzero(keep)
        tree = cKDTree(np.concatenate([np.column_stack([x[mass], y[mass]]), vertices[:, :2]]))
        a, b = vertices[segments[:, 0]], vertices[segments[:, 1]]
        mid, radius = (a[:, :2] + b[:, :2]) / 2, np.hypot(*(b[:, :2] - a[:, :2]).T) / 2
        inside = tree.query_ball_point(mid, radius * (1 - 1e-9), return_length=True)
        split = (inside > 0) & (radius >= min_length)
        for hits in tree.query_ball_point(mid[(inside > 0) & ~split], radius[(inside > 0) & ~split] * (1 - 1e-9)):
            hits = np.asarray(hits, int)
            keep[mass[hits[hits < len(mass)]]] = False
        if not split.any():
            break
        new = len(vertices) + np.arange(split.sum())
        vertices = np.concatenate([vertices, (a[split] + b[split]) / 2])
        segments = np.concatenate(
            [segments[~split], np.column_stack([segments[split, 0], new]), np.column_stack([new, segments[split, 1]])]
        )
    return vertices, segments, keep


@njit(cache=True, nogil=True)
def neighbour_residuals(indptr, indices, x, y, z, active, out):
    """out[i] = z[i] - the least-squares plane z = a + b dx + c dy through the active TIN neighbours of
    i (dx, dy relative to i, so the plane's value at i is a), for active i with at least 3 neighbours
    not on one line; NaN otherwise. Neighbours of i are indices[indptr[i]:indptr[i + 1]]."""
    for i in range(z.size):
        out[i] = np.nan
        if not active[i]:
            continue
        n = sx = sy = sz = sxx = sxy = syy = sxz = syz = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            if active[j]:
                dx, dy, zj = x[j] - x[i], y[j] - y[i], z[j]
                n += 1.0
                sx += dx
                sy += dy
                sz += zj
                sxx += dx * dx
                sxy += dx * dy
                syy += dy * dy
                sxz += dx * zj
                syz += dy * zj
        if n < 3.0:
            continue
        # normal equations [[n, sx, sy], [sx, sxx, sxy], [sy, sxy, syy]] (a, b, c) = (sz, sxz, syz), Cramer's rule
        c00 = sxx * syy - sxy * sxy
        c01 = sy * sxy - sx * syy
        c02 = sx * sxy - sy * sxx
        det = n * c00 + sx * c01 + sy * c02
        if not abs(det) > 1e-12 * abs(n * sxx * syy):
            continue
        out[i] = z[i] - (sz * c00 + sxz * c01 + syz * c02) / det


@njit(cache=True, nogil=True)
def local_maxima(indptr, indices, score, candidate, out):
    """out[i] = candidate[i] and score[i] >= the score of every candidate TIN neighbour of i (of a
    spike and the neighbours its plane fits pull along, only the spike is taken)."""
    for i in range(score.size):
        out[i] = candidate[i]
        if not candidate[i]:
            continue
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            if candidate[j] and score[j] > score[i]:
                out[i] = False
                break


#: the blunder filter's residuals are rounded to RESIDUAL_STEP (m), far below MIN_SIGMA, so that their
#: distribution is a sparse histogram (histogram.py) that the tiles of a tiled run add up exactly
RESIDUAL_STEP = 1e-3


class TileShare(NamedTuple):
    """A tile's share of a tiled run of the blunder filter: `spreads` the (centre, sigma) of each iteration
    given from outside (None: those of the tile's points), and `counted` the points the tile counts as its
    own (None: all)."""

    spreads: Sequence[tuple[float, float]] | None = None
    counted: np.ndarray | None = None


def filter_blunders(
    tin: Any,
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    k: float = 4.0,
    iterations: int = 3,
    fixed: np.ndarray | None = None,
    tile: TileShare | None = None,
) -> tuple[np.ndarray, list[int]]:
    """Points of `tin` (`delaunay(x, y)`) whose height departs from the plane fitted to their TIN
    neighbours by more than k robust sigmas: |r - centre| > k * sigma, r = neighbour_residuals rounded to
    RESIDUAL_STEP, with (centre, sigma) = spread of the tested points' r. Of neighbouring candidates only
    the largest |r| goes per iteration; each iteration recomputes r and the spread without the points
    already removed (on the same TIN), until no point is beyond k sigmas. Points where `fixed` is True
    (breakline vertices) are neighbours but never removed.

    `tile` (TileShare): its `spreads` are the (centre, sigma) of each iteration given from outside, one
    iteration per entry, instead of those of these points: a tiled run takes them from the
    residual_histogram of all tiles, so that its decisions do not depend on the tiling. Returns (keep mask,
    removed per iteration: of the points the tile's `counted` marks, default all)."""
    spreads, counted = tile or TileShare()
    x, y, z = (np.ascontiguousarray(v, float) for v in (x, y, z))
    keep = np.ones(len(z), bool)
    tested = np.ones(len(z), bool) if fixed is None else ~np.asarray(fixed, bool)
    removed: list[int] = []
    bad = np.empty(len(z), bool)
    for i in range(iterations if spreads is None else len(spreads)):
        r = _residual_steps(tin, x, y, z, keep)
        ok = np.isfinite(r) & tested
        if spreads is None:
            given = spread(histogram.count(r[ok]), k)
            if given is None or given[2] == 0:
                break
            centre, sigma = given[:2]
        else:
            centre, sigma = spreads[i]
        score = np.abs(r * RESIDUAL_STEP - centre)
        local_maxima(*tin.vertex_neighbor_vertices, np.nan_to_num(score), ok & (score > k * sigma), bad)
        removed.append(int(bad.sum() if counted is None else (bad & counted).sum()))
        keep &= ~bad
    return keep, removed


def _residual_steps(tin, x, y, z, keep):
    """neighbour_residuals of the kept points in whole RESIDUAL_STEPs (NaN where undefined)."""
    r = np.empty(len(z))
    neighbour_residuals(*tin.vertex_neighbor_vertices, x, y, z, keep, r)
    return np.round(r / RESIDUAL_STEP)


def residual_histogram(tin, x, y, z, keep, fixed=None, counted=None):
    """The histogram (histogram.count, bins of RESIDUAL_STEP) of the blunder filter's residuals r of the
    kept, tested points where `counted` is True (default all): a tile's share of an iteration's spread."""
    r = _residual_steps(tin, *(np.ascontiguousarray(v, float) for v in (x, y, z)), keep)
    ok = np.isfinite(r) & (True if fixed is None else ~np.asarray(fixed, bool)) & (True if counted is None else counted)
    return histogram.count(r[ok])


def spread(hist, k):
    """(centre, sigma, beyond) of a blunder filter iteration from the histogram of its residuals
    (residual_histogram, or the sum of the tiles'): the median of r, the robust sigma
    max(1.4826 * median(|r - centre|), MIN_SIGMA), and the count of points beyond k sigmas (0: the filter
    has converged); None with fewer than 3 residuals."""
    bins, counts = hist
    if counts.sum() < 3:
        return None
    r = bins * RESIDUAL_STEP
    centre = histogram.median(r, counts)
    deviation = np.abs(r - centre)
    sigma = max(NMAD_SCALE * histogram.median(deviation, counts), MIN_SIGMA)
    return centre, sigma, int(counts[deviation > k * sigma].sum())
