"""Epipolar images against the positions their grid gives: Keys' cubic reproduces a quadratic exactly,
so each sample must equal the quadratic at its grid position; NaN exactly where the support leaves the
image."""

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dense.epipolar import epipolar_grid
from pushbroom.algorithms.dense.resample import epipolar_image


def quadratic(x, y):
    return 100.0 + 0.3 * x - 0.2 * y + 1e-3 * x * y + 2e-4 * x * x


def test_epipolar_image_samples_the_image_at_the_grid_positions(pleiades_triplet):
    m1, m2 = sensors.load(pleiades_triplet[1]), sensors.load(pleiades_triplet[0])
    cols, rows = m1.size
    yy, xx = np.mgrid[0:rows, 0:cols] + 0.5
    img = quadratic(xx, yy)
    grid = epipolar_grid(m1, m2, (700, 700, 1000, 1000), (2000.0, 2600.0), step=16)
    epi = epipolar_image(img, grid.p, grid.step)
    assert epi.shape == grid.shape and epi.dtype == np.float32
    v, u = np.mgrid[0 : epi.shape[0], 0 : epi.shape[1]]
    x, y = grid.image1(grid.u0 + u, grid.v0 + v)
    inside = (x >= 2.5) & (y >= 2.5) & (x < cols - 2.5) & (y < rows - 2.5)
    assert inside.any() and (~inside).any()  # the tile's grid reaches past the image's edge
    assert (
        np.isfinite(epi[inside]).all()
        and np.isnan(epi[~inside & ((x < 1) | (y < 1) | (x > cols - 1) | (y > rows - 1))]).all()
    )
    assert np.abs(epi[inside] - quadratic(x[inside], y[inside])).max() < 2e-3


def test_nodata_spreads_over_the_cubic_support():
    img = np.full((40, 40), 7.0)
    img[20, 20] = np.nan
    nodes = np.stack(np.meshgrid(np.arange(0.5, 40, 8.0), np.arange(0.5, 40, 8.0)), axis=-1)[:5, :5]
    epi = epipolar_image(img, nodes, 8)
    bad = np.argwhere(np.isnan(epi[2:-2, 2:-2])) + 2
    # sample (i, j) sits at pixel centre (j + 0.5, i + 0.5): its 4 x 4 support is rows/cols i-1 .. i+2
    assert {tuple(b) for b in bad} == {(i, j) for i in range(18, 22) for j in range(18, 22)}
    assert np.allclose(epi[np.isfinite(epi)], 7.0)
