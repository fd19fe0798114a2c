"""The statistical outlier removal's distances and threshold (surface/outlier_filter.py) against plain numpy."""

import numpy as np
import pytest

from pushbroom.algorithms.surface.outlier_filter import margin, mean_distances, threshold


def test_mean_distances_against_all_pairs():
    rng = np.random.default_rng(5)
    pts = np.c_[rng.uniform(0, 100, 800), rng.uniform(0, 100, 800), rng.normal(50, 1, 800)]
    pts[:5, 2] += 40.0  # five blunders above the surface
    d = mean_distances(pts, pts[:200], 8)
    full = np.sqrt(((pts[:200, None, :] - pts[None, :, :]) ** 2).sum(axis=2))
    want = np.sort(full, axis=1)[:, 1:9].mean(axis=1)  # without the point's own zero
    assert d == pytest.approx(want, rel=1e-12)
    limit = threshold(d.size, d.sum(), np.square(d).sum(), 3.0)
    assert limit == pytest.approx(d.mean() + 3.0 * d.std(), rel=1e-9)
    assert set(np.flatnonzero(d > limit)) == set(range(5))
    assert np.isnan(mean_distances(pts[:8], pts[:3], 8)).all()  # fewer than k others


def test_margin_is_four_radii_of_k_plus_one_points():
    assert margin(10_000, 1e6, 20) == pytest.approx(4.0 * np.sqrt(21 * 100 / np.pi))
    assert margin(0, 1e6, 20) == 0.0
