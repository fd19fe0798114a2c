"""NCC along a path against numpy; peak, second peak, sub-pixel refinement, bad input."""

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms.matching import ncc


def textured(seed=0, size=80):
    rng = np.random.default_rng(seed)
    return (100 + 30 * ndimage.gaussian_filter(rng.normal(size=(size, size)), 2.0) / 0.14).astype(np.float32)


def test_ncc_path_against_numpy():
    img1, img2 = textured(0), textured(1)
    px = np.array([30.5, 31.25, 40.0, 77.0])
    py = np.array([30.5, 32.75, 41.3, 40.0])
    rho = np.empty(4)
    ncc.ncc_path(img1, img2, 35.5, 36.5, 4, px, py, 1.0, 0.1, -0.05, 0.5, rho)
    k, l = np.meshgrid(np.arange(-4, 5), np.arange(-4, 5))
    f = img1[32:41, 31:40].astype(float).ravel()
    for c in range(3):
        xs, ys = px[c] + k + 0.1 * l, py[c] - 0.05 * k + 0.5 * l
        g = ndimage.map_coordinates(img2.astype(float), [ys.ravel() - 0.5, xs.ravel() - 0.5], order=1)
        assert rho[c] == pytest.approx(np.corrcoef(f, g)[0, 1], abs=1e-6)
    assert np.isnan(rho[3])  # window leaves image 2
    ncc.ncc_path(img1, img1, 35.5, 36.5, 4, np.array([35.5]), np.array([36.5]), 1.0, 0.0, 0.0, 1.0, rho[:1])
    assert rho[0] == pytest.approx(1.0)  # the template itself


def test_ncc_path_peaks_at_the_shift_with_scale_two_to_one():
    rng = np.random.default_rng(3)
    base = ndimage.gaussian_filter(rng.normal(size=(120, 120)), 3.0).astype(np.float32)
    img2 = np.ascontiguousarray(base[::2, :])  # half the resolution along rows
    path_y = 30.0 + np.arange(-5, 6) * 0.5
    rho = np.empty(path_y.size)
    ncc.ncc_path(base, img2, 60.5, 60.5, 7, np.full(path_y.size, 60.5), path_y, 1.0, 0.0, 0.0, 0.5, rho)
    # image-1 row centre 60.5 -> array row 60 -> image-2 array row 30 -> y = 30.5
    assert path_y[np.nanargmax(rho)] == 30.5 and np.nanmax(rho) > 0.95


def test_ncc_path_is_nan_on_blank_windows():
    blank = np.full((50, 50), 3.0, np.float32)
    rho = np.empty(2)
    ncc.ncc_path(
        blank, textured(0, 50), 25.5, 25.5, 4, np.array([25.5, 26.5]), np.array([25.5, 25.5]), 1.0, 0.0, 0.0, 1.0, rho
    )
    assert np.isnan(rho).all()
    ncc.ncc_path(
        textured(0, 50), blank, 25.5, 25.5, 4, np.array([25.5, 26.5]), np.array([25.5, 25.5]), 1.0, 0.0, 0.0, 1.0, rho
    )
    assert np.isnan(rho).all()


def test_ncc_path_is_nan_where_a_masked_pixel_or_the_border_cuts_the_window():
    img1, img2 = textured(0, 50), textured(1, 50)
    rho = np.empty(3)
    # half 4: the window of x = 4.5 reaches the first pixel centre exactly (inside), of 4.4 beyond it
    px, py = np.array([25.5, 4.5, 4.4]), np.array([25.5, 45.5, 25.5])
    ncc.ncc_path(img1, img2, 25.5, 25.5, 4, px, py, 1.0, 0.0, 0.0, 1.0, rho)
    assert np.isfinite(rho[:2]).all() and np.isnan(rho[2])
    masked = img2.copy()
    masked[27, 23] = np.nan  # inside the first window only
    again = np.empty(3)
    ncc.ncc_path(img1, masked, 25.5, 25.5, 4, px, py, 1.0, 0.0, 0.0, 1.0, again)
    assert np.isnan(again[0]) and again[1] == rho[1]
