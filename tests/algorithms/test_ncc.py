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
    assert np.isnan(rho[3])                    # window leaves image 2
    ncc.ncc_path(img1, img1, 35.5, 36.5, 4, np.array([35.5]), np.array([36.5]), 1.0, 0.0, 0.0, 1.0, rho[:1])
    assert rho[0] == pytest.approx(1.0)        # the template itself


def test_ncc_search_finds_subpixel_shift_and_second_peak():
    rng = np.random.default_rng(2)
    base = ndimage.gaussian_filter(rng.normal(size=(100, 100)), 2.0)
    shift = 3.3
    img2 = ndimage.shift(base, (0.0, shift), order=3)   # content moves +3.3 px in x
    path_x = 50.5 + np.arange(-8, 9, 1.0)
    x, y, rho, second = ncc.ncc_search(base, img2, 50.5, 50.5, path_x, np.full(path_x.size, 50.5), template=15)
    assert x == pytest.approx(50.5 + shift, abs=0.15) and y == 50.5
    assert rho > 0.95 and second < rho


def test_ncc_scale_two_to_one():
    rng = np.random.default_rng(3)
    base = ndimage.gaussian_filter(rng.normal(size=(120, 120)), 3.0)
    img2 = base[::2, :]                          # half the resolution along rows
    path_y = 30.0 + np.arange(-5, 6) * 0.5
    x, y, rho, _ = ncc.ncc_search(base, img2, 60.5, 60.5, np.full(path_y.size, 60.5), path_y,
                                  affine=(1.0, 0.0, 0.0, 0.5))
    # image-1 row centre 60.5 -> array row 60 -> image-2 array row 30 -> y = 30.5
    assert y == pytest.approx(30.5, abs=0.15) and rho > 0.95


def test_ncc_blank_and_errors():
    blank = np.full((50, 50), 3.0, np.float32)
    assert np.isnan(ncc.ncc_search(blank, textured(0, 50), 25.5, 25.5, [25.5], [25.5])[2])
    assert np.isnan(ncc.ncc_search(textured(0, 50), blank, 25.5, 25.5, [25.5, 26.5], [25.5, 25.5])[0])
    from pushbroom.algorithms.errors import InputError
    with pytest.raises(InputError):
        ncc.ncc_search(blank, blank, 25.5, 25.5, [1.0], [1.0, 2.0])
    with pytest.raises(InputError):
        ncc.ncc_search(blank, blank, 25.5, 25.5, [1.0], [1.0], template=4)
