"""Image interpolation kernels against scipy and plain numpy."""

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms import interpolation


def keys_ref(t):
    t = abs(t)
    return np.where(t < 1, 1.5 * t**3 - 2.5 * t**2 + 1, np.where(t < 2, -0.5 * t**3 + 2.5 * t**2 - 4 * t + 2, 0.0))


def test_bilinear_against_scipy():
    rng = np.random.default_rng(0)
    img = rng.normal(size=(9, 11)).astype(np.float32)
    for x, y in rng.uniform(0.5, [10.5, 8.5], (50, 2)):
        ref = ndimage.map_coordinates(img.astype(float), [[y - 0.5], [x - 0.5]], order=1)[0]
        assert interpolation.bilinear(img, x, y) == pytest.approx(ref, abs=1e-5)
    assert interpolation.bilinear(img, 3.5, 4.5) == img[4, 3]  # pixel centre: exact value
    assert np.isnan(interpolation.bilinear(img, 0.2, 4.0))  # outside the pixel-centre hull


def test_bilinear_inside_equals_bilinear_up_to_the_hull_edges():
    rng = np.random.default_rng(2)
    img = rng.normal(size=(9, 11)).astype(np.float32)
    points = list(rng.uniform(0.5, [10.5, 8.5], (50, 2))) + [(0.5, 0.5), (10.5, 8.5), (10.5, 0.5), (0.5, 8.5)]
    for x, y in points:
        assert interpolation.bilinear_inside(img, x, y) == pytest.approx(interpolation.bilinear(img, x, y), abs=1e-6)


def test_cubic_against_numpy():
    rng = np.random.default_rng(1)
    img = rng.normal(size=(10, 12))
    for x, y in rng.uniform(1.5, [9.9, 7.9], (50, 2)):
        c, r = x - 0.5, y - 0.5
        j, i = np.arange(12), np.arange(10)
        ref = keys_ref(r - i) @ img @ keys_ref(c - j)
        g, kappa = interpolation.cubic(img, x, y)
        assert g == pytest.approx(ref, abs=1e-10)
        assert kappa == pytest.approx((keys_ref(c - j) ** 2).sum() * (keys_ref(r - i) ** 2).sum())
    assert interpolation.cubic(img, 4.5, 3.5)[0] == pytest.approx(img[3, 4])
