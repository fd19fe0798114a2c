"""Foerstner operator against a brute-force numpy loop; one point per patch; corner location."""

import numpy as np
import pytest

from pushbroom.algorithms.matching import interest


def test_foerstner_against_loop():
    rng = np.random.default_rng(0)
    img = rng.normal(size=(15, 17))
    w, q = interest.foerstner(img, 5)
    gx, gy = np.zeros_like(img), np.zeros_like(img)
    gx[:, 1:-1] = (img[:, 2:] - img[:, :-2]) / 2
    gy[1:-1] = (img[2:] - img[:-2]) / 2
    for i in range(3, 12):
        for j in range(3, 14):
            sx, sy = gx[i - 2 : i + 3, j - 2 : j + 3], gy[i - 2 : i + 3, j - 2 : j + 3]
            n = np.array([[(sx * sx).sum(), (sx * sy).sum()], [(sx * sy).sum(), (sy * sy).sum()]])
            assert w[i, j] == pytest.approx(np.linalg.det(n) / np.trace(n))
            assert q[i, j] == pytest.approx(4 * np.linalg.det(n) / np.trace(n) ** 2)


def test_corner_found_one_per_patch():
    img = np.zeros((64, 64))
    img[20:, 40:] = 100.0  # one corner at pixel edge (x, y) = (40, 20)
    x, y, w = interest.interest_points(img, patch=32, window=5)
    assert len(x) == 1 and abs(x[0] - 40) <= 1.5 and abs(y[0] - 20) <= 1.5
    rng = np.random.default_rng(1)
    x, y, w = interest.interest_points(rng.normal(size=(96, 128)), patch=32)
    cells = set(zip((x // 32).astype(int), (y // 32).astype(int)))
    assert len(cells) == len(x) and len(x) >= 10
    assert interest.interest_points(np.ones((64, 64)))[0].size == 0
