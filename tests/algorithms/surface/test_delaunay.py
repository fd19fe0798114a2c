"""The numba sweep-hull Delaunay triangulation (algorithms/surface/delaunay.py) against qhull (scipy.spatial) and
plain numpy in-circle tests, and tin.delaunay's use of it (qhull as the fallback, InputError where nothing works)."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull, Delaunay

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.surface import delaunay, tin


def triples(simplices, xy=None):
    """The triangles as a set of sorted vertex triples (of coordinate pairs where `xy` is given)."""
    if xy is None:
        return {tuple(sorted(s)) for s in np.asarray(simplices).tolist()}
    return {tuple(sorted(map(tuple, xy[s].tolist()))) for s in np.asarray(simplices)}


def signed_areas(x, y, s):
    """Twice the signed area of each triangle (> 0 counter-clockwise)."""
    return (x[s[:, 1]] - x[s[:, 0]]) * (y[s[:, 2]] - y[s[:, 0]]) - (y[s[:, 1]] - y[s[:, 0]]) * (x[s[:, 2]] - x[s[:, 0]])


def in_circle(ax, ay, bx, by, cx, cy, px, py):
    """The in-circle determinant of p against the counter-clockwise (a, b, c) (> 0 inside) and the sum of its
    absolute terms, in coordinates relative to p."""
    d = np.stack([np.stack([ax - px, ay - py]), np.stack([bx - px, by - py]), np.stack([cx - px, cy - py])])
    lift = (d**2).sum(axis=1)
    minors = [
        d[1, 0] * d[2, 1] - d[1, 1] * d[2, 0],
        d[2, 0] * d[0, 1] - d[2, 1] * d[0, 0],
        d[0, 0] * d[1, 1] - d[0, 1] * d[1, 0],
    ]
    return sum(lift[k] * minors[k] for k in range(3)), sum(lift[k] * np.abs(minors[k]) for k in range(3))


def empty_circumcircles(x, y, s):
    """Largest in-circle determinant of any point (not a vertex) against any triangle (all pairs)."""
    det, _ = in_circle(
        *(v[:, None] for v in (x[s[:, 0]], y[s[:, 0]], x[s[:, 1]], y[s[:, 1]], x[s[:, 2]], y[s[:, 2]])),
        x[None, :],
        y[None, :],
    )
    det[np.arange(len(s))[:, None], s] = -np.inf
    return det.max()


def locally_delaunay(x, y, t):
    """Largest relative in-circle determinant of the vertex across each inner edge (half-edges of `t`)."""
    s, he = t.simplices.ravel(), t.halfedges
    a = np.flatnonzero(he >= 0)
    b = he[a]
    nxt, prv = a - a % 3 + (a + 1) % 3, a - a % 3 + (a + 2) % 3
    far = s[b - b % 3 + (b + 2) % 3]
    det, terms = in_circle(x[s[prv]], y[s[prv]], x[s[a]], y[s[a]], x[s[nxt]], y[s[nxt]], x[far], y[far])
    return (det / terms).max()


def uniform(n, seed, size=1000.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-size / 2, size / 2, n), rng.uniform(-size / 2, size / 2, n)


@pytest.mark.parametrize("n, seed", [(3, 0), (4, 1), (10, 2), (100, 3), (5000, 4), (100_000, 5)])
def test_random_points_give_qhulls_triangles(n, seed):
    x, y = uniform(n, seed)
    t = delaunay.triangulate(x, y)
    assert t is not None
    assert triples(t.simplices) == triples(Delaunay(np.column_stack([x, y])).simplices)
    assert (signed_areas(x, y, t.simplices) > 0).all()


def test_neighbour_lists_are_qhulls():
    x, y = uniform(3000, 6)
    indptr, indices = delaunay.triangulate(x, y).vertex_neighbor_vertices
    ref_ptr, ref_ind = Delaunay(np.column_stack([x, y])).vertex_neighbor_vertices
    np.testing.assert_array_equal(np.diff(indptr), np.diff(ref_ptr))
    for k in range(len(x)):
        assert sorted(indices[indptr[k] : indptr[k + 1]]) == sorted(ref_ind[ref_ptr[k] : ref_ptr[k + 1]])


def test_distance_order_sorts_like_numpy():
    rng = np.random.default_rng(7)
    for dist in (
        rng.uniform(0, 1, 10_000),
        rng.exponential(1, 10_000) ** 4,  # skewed: large buckets
        np.round(rng.uniform(0, 50, 10_000)),
        np.zeros(100),
    ):  # ties; all equal
        order = delaunay.distance_order(dist)
        np.testing.assert_array_equal(np.sort(order), np.arange(len(dist)))
        np.testing.assert_array_equal(dist[order], np.sort(dist))


def test_integer_grid_has_empty_circumcircles():
    """Cocircular points everywhere: any of many triangulations is Delaunay. Small integers make numpy's in-circle
    determinant exact, so no point may lie strictly inside any triangle's circumcircle."""
    i, j = np.meshgrid(np.arange(-8.0, 9.0), np.arange(-7.0, 8.0))
    x, y = j.ravel(), i.ravel()
    t = delaunay.triangulate(x, y)
    assert t is not None
    assert empty_circumcircles(x, y, t.simplices) <= 0.0
    assert (signed_areas(x, y, t.simplices) > 0).all()
    assert len(t.simplices) == len(Delaunay(np.column_stack([x, y])).simplices) == 2 * 16 * 14


@pytest.mark.parametrize("cell, angle", [(0.1, 0.0), (0.3, 0.0), (0.5, 0.3), (1.0, np.pi / 4)])
def test_utm_grids_are_delaunay_within_rounding(cell, angle):
    """Grid points in UTM coordinates (not exact after tin.delaunay's shift to the mean): every circumcircle
    empty up to a relative 1e-9 of the determinant's terms, all triangles counter-clockwise, qhull's count."""
    i, j = np.meshgrid(np.arange(40.0), np.arange(30.0))
    u, v = cell * j.ravel(), cell * i.ravel()
    x = 612_345.67 + np.cos(angle) * u - np.sin(angle) * v
    y = 4_901_234.89 + np.sin(angle) * u + np.cos(angle) * v
    x, y = x - x.mean(), y - y.mean()
    t = delaunay.triangulate(x, y)
    assert t is not None
    assert locally_delaunay(x, y, t) < 1e-9
    assert (signed_areas(x, y, t.simplices) > 0).all()
    assert len(t.simplices) == len(Delaunay(np.column_stack([x, y])).simplices)


def test_duplicates_are_left_out_like_qhull_does():
    x, y = uniform(4000, 8)
    rng = np.random.default_rng(9)
    k = rng.choice(4000, 600)
    x, y = np.concatenate([x, x[k], x[:5]]), np.concatenate([y, y[k], y[:5]])
    t = delaunay.triangulate(x, y)
    assert t is not None
    xy = np.column_stack([x, y])
    assert triples(t.simplices, xy) == triples(Delaunay(xy).simplices, xy)
    used = np.unique(t.simplices)
    assert len(used) == len(np.unique(xy, axis=0))  # one of each set of duplicates
    indptr, _ = t.vertex_neighbor_vertices
    assert (np.diff(indptr)[np.setdiff1d(np.arange(len(x)), used)] == 0).all()


def test_quantised_coordinates_with_many_duplicates():
    """20 000 points rounded to a 1 m lattice of 101 x 101 positions: two thirds are duplicates, the rest a grid."""
    x, y = uniform(20_000, 10, size=100.0)
    x, y = np.round(x), np.round(y)
    t = delaunay.triangulate(x, y)
    assert t is not None
    assert len(np.unique(t.simplices)) == len(np.unique(np.column_stack([x, y]), axis=0))
    assert locally_delaunay(x, y, t) <= 0.0  # integers: exact
    assert len(t.simplices) == len(Delaunay(np.column_stack([x, y])).simplices)


@pytest.mark.parametrize("kind", ["clusters", "scan lines"])
def test_clustered_and_collinear_subsets(kind):
    """Tight clusters (1 mm in a 1 km square, where qhull drops points as coplanar) and points on 50 scan lines:
    every point used, triangles counter-clockwise and tiling the convex hull, every edge locally Delaunay."""
    rng = np.random.default_rng(11)
    if kind == "clusters":
        centres, which = rng.uniform(0, 1000, (20, 2)), rng.integers(0, 20, 20_000)
        x, y = centres[which, 0] + rng.normal(0, 1e-3, 20_000), centres[which, 1] + rng.normal(0, 1e-3, 20_000)
    else:
        x, y = rng.uniform(0, 1000, 20_000), 20.0 * rng.integers(0, 50, 20_000)
    x, y = x - x.mean(), y - y.mean()
    t = delaunay.triangulate(x, y)
    assert t is not None
    assert len(np.unique(t.simplices)) == len(x)
    area = signed_areas(x, y, t.simplices)
    assert (area > 0).all()
    assert np.isclose(area.sum() / 2, ConvexHull(np.column_stack([x, y])).volume, rtol=1e-9)
    assert locally_delaunay(x, y, t) < 1e-9


def test_collinear_points():
    x = np.arange(10.0)
    assert delaunay.triangulate(x, 2 * x) is None
    with pytest.raises(InputError, match="one line"):
        tin.delaunay(x, 2 * x)
    x, y = np.append(x, 3.0), np.append(2 * x, 0.0)  # one point off the line: a fan
    t = delaunay.triangulate(x, y)
    assert triples(t.simplices) == triples(Delaunay(np.column_stack([x, y])).simplices) and len(t.simplices) == 9


def test_not_finite_or_too_few_points():
    x, y = uniform(50, 12)
    x[7] = np.nan
    assert delaunay.triangulate(x, y) is None
    with pytest.raises(InputError, match="not finite"):
        tin.delaunay(x, y)
    with pytest.raises(InputError, match="at least 3"):
        tin.delaunay(x[:2], y[:2])


def test_tin_delaunay_sweeps_and_falls_back_to_qhull():
    """tin.delaunay takes the sweep's result where it passes its check; points on one circle (every in-circle
    determinant rounding noise) may fail it, and the answer is then qhull's: Delaunay either way."""
    x, y = uniform(2000, 13)
    tin_ = tin.delaunay(x + 600_000, y + 4_900_000)
    assert isinstance(tin_, delaunay.Triangulation)
    assert triples(tin_.simplices) == triples(Delaunay(np.column_stack([x - x.mean(), y - y.mean()])).simplices)
    angle = np.random.default_rng(14).uniform(0, 2 * np.pi, 2000)
    x, y = np.cos(angle), np.sin(angle)
    circle = tin.delaunay(x, y)
    assert len(circle.simplices) == 1998 and (signed_areas(x, y, np.asarray(circle.simplices)) != 0).all()


def test_check_accepts_only_a_delaunay_triangulation():
    """Four points of a convex quad whose diagonal 0-2 has point 3 inside the circumcircle of (0, 1, 2) (centre
    (1, 0), radius 1): the diagonal 1-3 passes the check, 0-2 fails it, so do broken twins and a missing point."""
    x, y = np.array([0.0, 1.0, 2.0, 1.0]), np.array([0.0, -1.0, 0.0, 0.2])
    hull_next = np.array([1, 2, 3, 0], np.int32)

    def check(tri, halfedges, points=4):
        return delaunay.check(x, y, np.array(tri, np.int32), np.array(halfedges, np.int32), hull_next, 0, points)

    assert check([0, 1, 3, 1, 2, 3], [-1, 5, -1, -1, -1, 1])
    assert not check([0, 1, 2, 0, 2, 3], [-1, -1, 3, 2, -1, -1])  # not locally Delaunay
    assert not check([0, 1, 3, 1, 2, 3], [-1, 5, -1, -1, -1, 2])  # twins inconsistent
    assert not check([0, 1, 3, 1, 2, 3], [-1, 5, -1, -1, -1, 1], points=5)  # Euler: a point left out
    assert not check([0, 3, 1, 1, 3, 2], [-1, 3, -1, 1, -1, -1])  # clockwise triangles
