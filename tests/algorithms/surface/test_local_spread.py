"""The local height spread (surface/local_spread.py) against a plain numpy loop, and the same spread from any
subset of the cloud that holds the square around the query."""

import numpy as np
import pytest

from pushbroom.algorithms.surface.local_spread import MIN_POINTS, REACH, local_metres, local_spread, reach_m


def reference(x, y, h, qx, qy, radius):
    """Per query: the population std of the heights in the (2 REACH + 1)^2 cells of size 2 R / 5 around its cell."""
    g = 2.0 * radius / (2 * REACH + 1)
    out = np.full(qx.size, np.nan)
    for k in range(qx.size):
        m = (np.abs(np.floor(x / g) - np.floor(qx[k] / g)) <= REACH) & (
            np.abs(np.floor(y / g) - np.floor(qy[k] / g)) <= REACH
        )
        if m.sum() >= MIN_POINTS:
            out[k] = np.std(h[m])
    return out


def test_spread_against_a_loop_over_the_queries():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-200, 300, 4000), rng.uniform(-150, 250, 4000)
    h = 500.0 + 0.05 * x + np.where(x > 100, 20.0, 0.0) + rng.normal(0, 0.5, x.size)
    qx, qy = rng.uniform(-260, 360, 300), rng.uniform(-210, 310, 300)
    got = local_spread(x, y, h, qx, qy, 25.0)
    want = reference(x, y, h, qx, qy, 25.0)
    assert np.array_equal(np.isnan(got), np.isnan(want)) and np.isnan(got).any() and np.isfinite(got).sum() > 200
    assert np.allclose(got, want, rtol=1e-9, atol=1e-9, equal_nan=True)
    # the step at x = 100 m: a square across it sees both heights
    across = np.isfinite(got) & (np.abs(qx - 100) < 5)
    flat = np.isfinite(got) & (qx < 0)
    assert np.median(got[across]) > 5.0 and np.median(got[flat]) < 2.0


def test_a_tile_with_its_neighbourhood_gives_the_cloud_s_spread():
    rng = np.random.default_rng(4)
    x, y = rng.uniform(0, 400, 6000), rng.uniform(0, 400, 6000)
    h = rng.normal(100, 3, x.size)
    tile = (x < 200) & (y < 200)
    margin = reach_m(20.0)
    assert margin == pytest.approx(24.0)  # 3 cells of 8 m
    near = (x < 200 + margin) & (y < 200 + margin)
    whole = local_spread(x, y, h, x[tile], y[tile], 20.0)
    part = local_spread(x[near], y[near], h[near], x[tile], y[tile], 20.0)
    assert np.allclose(whole, part, equal_nan=True)


def test_local_metres_of_the_centre_and_a_degree():
    x, y = local_metres(np.array([10.0, 10.001]), np.array([45.0, 45.001]), (10.0, 45.0))
    assert x[0] == 0 and y[0] == 0
    assert x[1] == pytest.approx(78.85, abs=0.05) and y[1] == pytest.approx(111.13, abs=0.05)
