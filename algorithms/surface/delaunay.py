"""2-D Delaunay triangulation by the sweep-hull method of Delaunator (V. Agafonkin, github.com/mapbox/delaunator).

A seed triangle near the centre (its circumcircle holds no other point); the points in order of distance from
its circumcentre, so each one lies outside the hull built so far; a triangle from the point to every hull edge
it sees (the first one found through a hash of pseudo-angles about the centre), each followed by Lawson flips of
the edges opposite the point (explicit stack) until they are locally Delaunay. Half-edge e runs from tri[e] to
tri[next(e)] in triangle e // 3 (counter-clockwise), its twin is halfedges[e] (-1 on the hull).

Floating-point predicates with relative tolerances: collinear within ORIENT_EPS of the orientation's terms (no
flat triangle from collinear points), a flip only where the in-circle determinant exceeds INCIRCLE_EPS of its
terms (cocircular grids keep their first diagonal). A point that sees no hull edge is an exact duplicate of a seed
or of an earlier point at the same distance, left out as qhull does (or lost). `triangulate` checks the result (no
lost point, every triangle counter-clockwise, twins consistent, convex hull, Euler count T = 2 n - 2 - h, every edge
locally Delaunay) and returns None where it fails, for the caller to fall back to qhull."""

from __future__ import annotations

from functools import cached_property
from typing import NamedTuple

import numpy as np
from numba import njit, prange

#: relative tolerance of the orientation test (Shewchuk's error bound is 3.3e-16)
ORIENT_EPS = 1e-13
#: relative tolerance of the in-circle test (Shewchuk's error bound is 1.1e-15)
INCIRCLE_EPS = 1e-13


class Triangulation:
    """What tin.py uses of scipy's Delaunay: `simplices` (m, 3) counter-clockwise vertex indices and
    `vertex_neighbor_vertices` (indptr, indices), the neighbours of k being indices[indptr[k]:indptr[k + 1]]."""

    def __init__(self, simplices, halfedges, npoints):
        self.simplices = simplices
        self.halfedges = halfedges
        self.npoints = npoints

    @cached_property
    def vertex_neighbor_vertices(self):
        indptr = np.zeros(self.npoints + 1, np.int32)
        indices = np.empty(2 * self.halfedges.size, np.int32)
        used = neighbour_lists(self.simplices.ravel(), self.halfedges, indptr, indices)
        return indptr, indices[:used]


@njit(cache=True, nogil=True)
def orient(ax, ay, bx, by, cx, cy):
    """(b - a) x (c - a): > 0 where (a, b, c) turn counter-clockwise; 0 within ORIENT_EPS of its terms."""
    left = (bx - ax) * (cy - ay)
    right = (by - ay) * (cx - ax)
    if abs(left - right) <= ORIENT_EPS * (abs(left) + abs(right)):
        return 0.0
    return left - right


@njit(cache=True, nogil=True)
def in_circle(ax, ay, bx, by, cx, cy, px, py, eps):
    """Whether p lies inside the circle through the counter-clockwise (a, b, c): det [d_x, d_y, d_x^2 + d_y^2]
    over d = a - p, b - p, c - p > eps times the sum of its absolute terms."""
    dx, dy, ex, ey, fx, fy = ax - px, ay - py, bx - px, by - py, cx - px, cy - py
    ap, bp, cp = dx * dx + dy * dy, ex * ex + ey * ey, fx * fx + fy * fy
    det = ap * (ex * fy - ey * fx) + bp * (fx * dy - fy * dx) + cp * (dx * ey - dy * ex)
    if det <= 0.0:
        return False
    terms = ap * (abs(ex * fy) + abs(ey * fx)) + bp * (abs(fx * dy) + abs(fy * dx)) + cp * (abs(dx * ey) + abs(dy * ex))
    return det > eps * terms


@njit(cache=True, nogil=True)
def seed(x, y):
    """Seed triangle (i0, i1, i2), counter-clockwise: i0 nearest the bounding-box centre, i1 nearest i0, i2 of
    the smallest circumcircle through both (not collinear); i2 = -1 where every point is on one line."""
    mx, my = (x.min() + x.max()) / 2, (y.min() + y.max()) / 2
    i0 = np.argmin((x - mx) ** 2 + (y - my) ** 2)
    d = (x - x[i0]) ** 2 + (y - y[i0]) ** 2
    d[d == 0.0] = np.inf
    i1 = np.argmin(d)
    i2, best = -1, np.inf
    bx, by = x[i1] - x[i0], y[i1] - y[i0]
    for i in range(x.size):
        if orient(x[i0], y[i0], x[i1], y[i1], x[i], y[i]) == 0.0:
            continue
        cx, cy = x[i] - x[i0], y[i] - y[i0]
        b2, c2, det = bx * bx + by * by, cx * cx + cy * cy, 2 * (bx * cy - by * cx)
        r2 = ((cy * b2 - by * c2) ** 2 + (bx * c2 - cx * b2) ** 2) / (det * det)
        if r2 < best:
            i2, best = i, r2
    if i2 >= 0 and orient(x[i0], y[i0], x[i1], y[i1], x[i2], y[i2]) < 0:
        i1, i2 = i2, i1
    return i0, i1, i2


@njit(cache=True, nogil=True)
def circumcentre(ax, ay, bx, by, cx, cy):
    """Centre of the circle through a, b, c (not collinear)."""
    bx, by, cx, cy = bx - ax, by - ay, cx - ax, cy - ay
    b2, c2, det = bx * bx + by * by, cx * cx + cy * cy, 2 * (bx * cy - by * cx)
    return ax + (cy * b2 - by * c2) / det, ay + (bx * c2 - cx * b2) / det


@njit(cache=True, nogil=True)
def hash_key(x, y, cx, cy, size):
    """Bucket of the pseudo-angle of (x - cx, y - cy), monotonic in the angle: [0, 1) -> [0, size)."""
    dx, dy = x - cx, y - cy
    s = abs(dx) + abs(dy)
    if s == 0.0:
        return 0
    p = dx / s
    angle = (3.0 - p if dy > 0 else 1.0 + p) / 4.0
    return int(angle * size) % size


@njit(cache=True, nogil=True)
def link(halfedges, a, b):
    """Make half-edges a and b (-1: none) twins."""
    halfedges[a] = b
    if b >= 0:
        halfedges[b] = a


@njit(cache=True, nogil=True)
def add_triangle(tri, halfedges, t, i0, i1, i2, a, b, c):
    """Triangle (i0, i1, i2) at half-edge t, its half-edges' twins a, b, c (-1: none)."""
    tri[t], tri[t + 1], tri[t + 2] = i0, i1, i2
    link(halfedges, t, a)
    link(halfedges, t + 1, b)
    link(halfedges, t + 2, c)


@njit(cache=True, nogil=True)
def legalize(a, x, y, tri, halfedges, hull_start, hull_prev, hull_tri, stack):
    """Flip half-edge a (opposite the new point p0) and the edges each flip uncovers while p0 lies in the
    circumcircle across them. Returns the half-edge that follows p0 in the last triangle checked (p0's outgoing
    hull edge when a was the far edge of p0's newest triangle)."""
    top = 0
    while True:
        b = halfedges[a]
        a0 = a - a % 3
        ar, al = a0 + (a + 2) % 3, a0 + (a + 1) % 3
        b0 = b - b % 3
        bl, br = b0 + (b + 2) % 3, b0 + (b + 1) % 3
        if b == -1 or not in_circle(
            x[tri[ar]], y[tri[ar]], x[tri[a]], y[tri[a]], x[tri[al]], y[tri[al]], x[tri[bl]], y[tri[bl]], INCIRCLE_EPS
        ):
            if top == 0:
                return ar
            top -= 1
            a = stack[top]
            continue
        # (p0, pr, pl) + (pl, pr, p1) -> (p0, p1, pl) + (p0, pr, p1)
        tri[a], tri[b] = tri[bl], tri[ar]
        hbl = halfedges[bl]
        if hbl == -1:  # the edge p1 -> pl lies on the hull: its half-edge moved from bl to a
            e = hull_start
            while True:
                if hull_tri[e] == bl:
                    hull_tri[e] = a
                    break
                e = hull_prev[e]
                if e == hull_start:
                    break
        link(halfedges, a, hbl)
        link(halfedges, b, halfedges[ar])
        link(halfedges, ar, bl)
        stack[top] = br
        top += 1


class Hull(NamedTuple):
    """The convex hull as the sweep builds it, per point (int32 arrays of n): `next` and `prev` its
    neighbours along the hull (next[k] == k: no longer on it), `tri` the half-edge of its outgoing hull edge."""

    next: np.ndarray
    prev: np.ndarray
    tri: np.ndarray


@njit(cache=True, nogil=True)
def sweep(
    x: np.ndarray,
    y: np.ndarray,
    dist: np.ndarray,
    i0: int,
    i1: int,
    i2: int,
    cx: float,
    cy: float,
    tri: np.ndarray,
    halfedges: np.ndarray,
    hull: Hull,
) -> tuple[int, int, int, int]:
    """Insert the points, sorted by `dist` from the seed circumcentre (cx, cy), around the seed triangle
    (i0, i1, i2), into the half-edges (tri, halfedges) and the `hull`. Returns (half-edges used, hull start,
    exact duplicates left out, points that found no visible hull edge)."""
    hull_next, hull_prev, hull_tri = hull
    n = x.size
    size = max(int(np.ceil(np.sqrt(n))), 1)
    hull_hash = np.full(size, -1, np.int64)
    stack = np.empty(2 * n + 8, np.int32)  # a flip adds a triangle at the new point: at most 2 n
    hull_next[i0], hull_next[i1], hull_next[i2] = i1, i2, i0
    hull_prev[i0], hull_prev[i1], hull_prev[i2] = i2, i0, i1
    hull_tri[i0], hull_tri[i1], hull_tri[i2] = 0, 1, 2
    for s in (i0, i1, i2):
        hull_hash[hash_key(x[s], y[s], cx, cy, size)] = s
    add_triangle(tri, halfedges, 0, i0, i1, i2, -1, -1, -1)
    used, hull_start, duplicates, lost = 3, i0, 0, 0
    for i in range(n):
        px, py = x[i], y[i]
        if i == i0 or i == i1 or i == i2:
            continue
        key = hash_key(px, py, cx, cy, size)
        start = i0
        for m in range(size):
            start = hull_hash[(key + m) % size]
            if start != -1 and start != hull_next[start]:
                break
        start = hull_prev[start]
        e = start
        while orient(x[e], y[e], x[hull_next[e]], y[hull_next[e]], px, py) >= 0.0:
            e = hull_next[e]
            if e == start:
                e = -1
                break
        if e == -1:  # inside the hull: an exact duplicate of a seed or an earlier point at the same distance
            duplicate = (x[i0] == px and y[i0] == py) or (x[i1] == px and y[i1] == py) or (x[i2] == px and y[i2] == py)
            j = i - 1
            while not duplicate and j >= 0 and dist[j] == dist[i]:
                duplicate = x[j] == px and y[j] == py
                j -= 1
            duplicates += duplicate
            lost += not duplicate
            continue
        add_triangle(tri, halfedges, used, e, i, hull_next[e], -1, -1, hull_tri[e])
        hull_tri[i] = legalize(used + 2, x, y, tri, halfedges, hull_start, hull_prev, hull_tri, stack)
        hull_tri[e] = used
        used += 3
        nxt = hull_next[e]
        q = hull_next[nxt]
        while q != e and orient(x[nxt], y[nxt], x[q], y[q], px, py) < 0.0:
            add_triangle(tri, halfedges, used, nxt, i, q, hull_tri[i], -1, hull_tri[nxt])
            hull_tri[i] = legalize(used + 2, x, y, tri, halfedges, hull_start, hull_prev, hull_tri, stack)
            used += 3
            hull_next[nxt] = nxt
            nxt, q = q, hull_next[q]
        if e == start:
            q = hull_prev[e]
            while q != nxt and orient(x[q], y[q], x[e], y[e], px, py) < 0.0:
                add_triangle(tri, halfedges, used, q, i, e, -1, hull_tri[e], hull_tri[q])
                legalize(used + 2, x, y, tri, halfedges, hull_start, hull_prev, hull_tri, stack)
                hull_tri[q] = used
                used += 3
                hull_next[e] = e
                e, q = q, hull_prev[q]
        hull_start = e
        hull_prev[i], hull_next[e], hull_prev[nxt], hull_next[i] = e, i, i, nxt
        hull_hash[key] = i
        hull_hash[hash_key(x[e], y[e], cx, cy, size)] = e
    return used, hull_start, duplicates, lost


@njit(cache=True, nogil=True, parallel=True)
def defects(x, y, tri, halfedges):
    """(triangles not counter-clockwise + half-edges whose twin is inconsistent or whose edge is not locally
    Delaunay within 10 INCIRCLE_EPS, hull half-edges)."""
    bad = 0
    outer = 0
    for a in prange(tri.size):
        a0 = a - a % 3
        a1, a2 = a0 + (a + 1) % 3, a0 + (a + 2) % 3
        if a == a0 and not orient(x[tri[a]], y[tri[a]], x[tri[a1]], y[tri[a1]], x[tri[a2]], y[tri[a2]]) > 0.0:
            bad += 1
        b = halfedges[a]
        if b == -1:
            outer += 1
            continue
        b1, b2 = b - b % 3 + (b + 1) % 3, b - b % 3 + (b + 2) % 3
        if halfedges[b] != a or tri[a] != tri[b1] or tri[b] != tri[a1]:
            bad += 1
        elif a < b and in_circle(
            x[tri[a2]],
            y[tri[a2]],
            x[tri[a]],
            y[tri[a]],
            x[tri[a1]],
            y[tri[a1]],
            x[tri[b2]],
            y[tri[b2]],
            10 * INCIRCLE_EPS,
        ):
            bad += 1
    return bad, outer


@njit(cache=True, nogil=True)
def hull_length(x, y, hull_next, hull_start):
    """Number of points on the hull cycle from hull_start; -1 where it is not a convex cycle."""
    h, e = 0, hull_start
    while True:
        prev, e = e, hull_next[e]
        h += 1
        if h > x.size or orient(x[prev], y[prev], x[e], y[e], x[hull_next[e]], y[hull_next[e]]) < 0.0:
            return -1
        if e == hull_start:
            return h


def check(x, y, tri, halfedges, hull_next, hull_start, points):
    """Whether the half-edges are a Delaunay triangulation of `points` distinct points: no `defects`, a convex
    hull cycle of h points with as many hull half-edges, and T = 2 n - 2 - h triangles (Euler)."""
    bad, outer = defects(x, y, tri, halfedges)
    h = hull_length(x, y, hull_next, hull_start)
    return bad == 0 and h == outer and tri.size // 3 == 2 * points - 2 - h


@njit(cache=True, nogil=True)
def distance_order(dist):
    """Indices that sort `dist` (finite, >= 0): a counting sort into n buckets of equal width, then insertion
    sort (numpy's argsort beyond 32) within each bucket."""
    n = dist.size
    scale = n / dist.max() if dist.max() > 0 else 0.0
    key = np.minimum((dist * scale).astype(np.int64), n - 1)
    start = np.zeros(n + 1, np.int64)
    for i in range(n):
        start[key[i] + 1] += 1
    for k in range(n):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    order = np.empty(n, np.int32)
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    for k in range(n):
        lo, hi = start[k], start[k + 1]
        if hi - lo > 32:
            order[lo:hi] = order[lo:hi][np.argsort(dist[order[lo:hi]])]
            continue
        for i in range(lo + 1, hi):
            v, j = order[i], i - 1
            while j >= lo and dist[order[j]] > dist[v]:
                order[j + 1] = order[j]
                j -= 1
            order[j + 1] = v
    return order


@njit(cache=True, nogil=True)
def neighbour_lists(tri, halfedges, indptr, indices):
    """CSR neighbour lists (indptr (n + 1,) zeros on entry, indices) of the vertices: the end of every half-edge
    leaving a vertex, and the start of its hull half-edge arriving. Returns the number of indices."""
    n = tri.size
    for a in range(n):
        indptr[tri[a] + 1] += 1
        if halfedges[a] == -1:
            indptr[tri[a - a % 3 + (a + 1) % 3] + 1] += 1
    for k in range(1, indptr.size):
        indptr[k] += indptr[k - 1]
    fill = indptr[:-1].copy()
    for a in range(n):
        u, v = tri[a], tri[a - a % 3 + (a + 1) % 3]
        indices[fill[u]] = v
        fill[u] += 1
        if halfedges[a] == -1:
            indices[fill[v]] = u
            fill[v] += 1
    return indptr[-1]


def triangulate(x, y):
    """Delaunay triangulation (Triangulation) of the points (x, y), best centred on their mean; None where they
    are fewer than 3, not finite, on one line, or the sweep's result fails `check` (fall back to qhull)."""
    x, y = (np.ascontiguousarray(v, np.float64) for v in (x, y))
    n = x.size
    if n < 3 or not (np.isfinite(x).all() and np.isfinite(y).all()):
        return None
    i0, i1, i2 = seed(x, y)
    if i2 < 0:
        return None
    cx, cy = circumcentre(x[i0], y[i0], x[i1], y[i1], x[i2], y[i2])
    dist = (x - cx) ** 2 + (y - cy) ** 2
    order = distance_order(dist)  # the sweep numbers the points in this order (locality)
    x, y, dist = x[order], y[order], dist[order]
    i0, i1, i2 = (int(np.argmax(order == i)) for i in (i0, i1, i2))
    tri, halfedges = np.empty(6 * n, np.int32), np.empty(6 * n, np.int32)
    hull = Hull(*(np.empty(n, np.int32) for _ in range(3)))
    used, hull_start, duplicates, lost = sweep(x, y, dist, i0, i1, i2, cx, cy, tri, halfedges, hull)
    tri, halfedges = tri[:used], halfedges[:used]
    if lost or not check(x, y, tri, halfedges, hull.next, hull_start, n - duplicates):
        return None
    return Triangulation(order[tri].reshape(-1, 3), halfedges, n)
