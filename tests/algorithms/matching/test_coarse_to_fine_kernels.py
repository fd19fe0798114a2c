"""Candidates of all points in one kernel (coarse_to_fine_kernels.path_candidates) against the known
shift of a synthetic pair and against ncc.ncc_path per point."""

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms.matching import ncc
from pushbroom.algorithms.matching.coarse_to_fine_kernels import Affines, Found, Paths, path_candidates


def test_path_candidates_find_the_shift():
    """img2 is img1 moved by 3.3 px in x: along a path over x (height = x offset) the best candidate
    lies at the shift, its rho is ncc_path's best score, and a point without texture has none."""
    rng = np.random.default_rng(4)
    img1 = 100 + 30 * ndimage.gaussian_filter(rng.normal(size=(90, 90)), 2.0) / 0.14
    img1[:, 70:] = 100.0  # blank strip
    img2 = ndimage.shift(img1, (0.0, 3.3), order=3, mode="nearest")
    img1, img2 = img1.astype(np.float32), img2.astype(np.float32)  # as the matcher reads images
    x = np.array([30.5, 45.5, 80.5])
    y = np.array([40.5, 50.5, 40.5])
    k, off = 41, np.arange(-2.0, 3.0)
    t = np.linspace(0.0, 8.0, k)  # path x offsets = "heights"
    cx = x[:, None, None] + t[None, :, None] + 0.0 * off
    cy = y[:, None, None] + 0.0 * t[None, :, None] + off
    heights = np.tile(t, (3, 1))
    half = np.array([5, 5, 5])
    one = np.ones(3)
    out = [np.full((3, 2), np.nan) for _ in range(4)]
    second = np.full(3, np.nan)
    path_candidates(
        img1,
        img2,
        x,
        y,
        half,
        Paths(cx, cy, heights),
        Affines(one, 0 * one, 0 * one, one),
        np.full(3, 0.7),
        Found(*out),
        second,
    )
    h, rho, px, py = out
    assert np.allclose(h[:2, 0], 3.3, atol=0.05)
    assert np.allclose(px[:2, 0], x[:2] + h[:2, 0]) and np.allclose(py[:2, 0], y[:2], atol=0.05)
    for i in range(2):
        scores = np.empty(k * len(off))
        ncc.ncc_path(img1, img2, x[i], y[i], 5, cx[i].ravel(), cy[i].ravel(), 1.0, 0.0, 0.0, 1.0, scores)
        assert rho[i, 0] == pytest.approx(np.nanmax(scores), abs=1e-12) and rho[i, 0] > 0.99
        assert not rho[i, 1] > rho[i, 0]  # best first
    assert np.isnan(h[2]).all() and np.isnan(second[2])
