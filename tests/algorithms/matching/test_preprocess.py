"""Preprocessing (algorithms/matching/preprocess.py): Wallis filter, Saint-Marc adaptive smoothing and the
image pyramid against independent numpy / scipy.ndimage references; edge preservation, 16-bit depth, the
pyramid's coordinate convention and the number of levels."""

import warnings

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching import preprocess


def wallis_reference(img, window, mf, sf, c, b):
    """Window statistics of the valid pixels by scipy.ndimage box sums (zero outside the image)."""
    img = img.astype(np.float64)
    valid = np.isfinite(img)
    v = np.where(valid, img, 0.0)
    box = lambda a: ndimage.uniform_filter(a, window, mode="constant") * window**2
    n = box(valid.astype(np.float64))
    with np.errstate(divide="ignore", invalid="ignore"):  # n = 0 inside large holes
        mw = box(v) / n
        sw = np.sqrt(np.maximum(box(v * v) / n - mw**2, 0.0))
    r1 = c * sf / (c * sw + (1 - c) * sf)
    return np.where(valid, (img - mw) * r1 + b * mf + (1 - b) * mw, np.nan)


def saint_marc_reference(img, k, iterations):
    """Plain numpy: neighbours by shifting a NaN-padded copy."""
    a = img.astype(np.float64)
    rows, cols = a.shape
    for _ in range(iterations):
        p = np.pad(a, 1, constant_values=np.nan)
        nb = lambda di, dj: p[1 + di : 1 + di + rows, 1 + dj : 1 + dj + cols]
        fill = lambda q: np.where(np.isnan(q), a, q)
        g2 = ((fill(nb(0, 1)) - fill(nb(0, -1))) ** 2 + (fill(nb(1, 0)) - fill(nb(-1, 0))) ** 2) / 4
        w = np.pad(np.where(np.isnan(a), 0.0, np.exp(-g2 / (2 * k * k))), 1)
        sw = sum(w[1 + di : 1 + di + rows, 1 + dj : 1 + dj + cols] for di in (-1, 0, 1) for dj in (-1, 0, 1))
        swi = sum(
            w[1 + di : 1 + di + rows, 1 + dj : 1 + dj + cols] * np.nan_to_num(nb(di, dj))
            for di in (-1, 0, 1)
            for dj in (-1, 0, 1)
        )
        a = np.where(np.isnan(a), np.nan, swi / sw)
    return a


def block_mean_reference(img, f):
    """nanmean over f x f blocks of a NaN-padded copy (all-NaN blocks give NaN)."""
    rows, cols = -(-img.shape[0] // f) * f, -(-img.shape[1] // f) * f
    p = np.full((rows, cols), np.nan)
    p[: img.shape[0], : img.shape[1]] = img
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # "mean of empty slice"
        return np.nanmean(p.reshape(rows // f, f, cols // f, f), axis=(1, 3))


def sixteen_bit_image(shape, seed):
    """uint16 texture spanning most of the 16-bit range (smoothed noise), values far above 255."""
    rng = np.random.default_rng(seed)
    t = ndimage.gaussian_filter(rng.normal(size=shape), 1.5)
    t = (t - t.min()) / (t.max() - t.min())
    return (2000 + 60000 * t).astype(np.uint16)


@pytest.mark.parametrize("window", [3, 7, 41])
def test_wallis_against_ndimage(window):
    img = sixteen_bit_image((23, 31), 0).astype(np.float32)
    img[5:8, 10:14] = np.nan  # nodata: excluded and kept
    img[0, 0] = np.nan
    got = preprocess.wallis(img, window, 127.0, 50.0, 0.8, 0.9)
    ref = wallis_reference(img, window, 127.0, 50.0, 0.8, 0.9)
    assert got.dtype == np.float32
    assert np.array_equal(np.isnan(got), np.isnan(img))
    np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-3)


def test_wallis_stretches_16bit_detail_lost_in_8_bits():
    """A +-2 DN checkerboard on 3000 DN (uint16): with c = b = 1 every pixel goes to m_f +- s_f; the
    same image reduced to 8 bits (top byte) is constant."""
    i, j = np.indices((60, 80))
    img = (3000 + 2 * np.where((i + j) % 2, 1, -1)).astype(np.uint16)
    assert np.unique(img >> 8).size == 1
    out = preprocess.wallis(img, 21, 127.0, 50.0, contrast=1.0, brightness=1.0)
    sign = np.where((i + j) % 2, 1, -1)
    np.testing.assert_allclose(out, 127.0 + 50.0 * sign, atol=0.5)
    flat = preprocess.wallis(np.full((30, 30), 4000, np.uint16), 21)
    np.testing.assert_allclose(flat, 0.9 * 127.0 + 0.1 * 4000.0, rtol=1e-6)  # r0 where s_w = 0


def test_saint_marc_against_numpy_reference():
    img = sixteen_bit_image((19, 26), 1).astype(np.float32)
    img[4, 4:9] = np.nan
    img[-1, -1] = np.nan
    k = 800.0
    got = preprocess.saint_marc(img, k=k, iterations=3)
    ref = saint_marc_reference(img, k, 3)
    assert got.dtype == np.float32 and np.nanmax(got) > 255
    assert np.array_equal(np.isnan(got), np.isnan(img))
    np.testing.assert_allclose(got, ref, rtol=2e-6)
    assert np.abs(got - img)[np.isfinite(img)].max() > 10  # it did smooth something


def test_saint_marc_keeps_step_edge_and_removes_noise():
    rng = np.random.default_rng(2)
    clean = np.where(np.arange(64) < 32, 1000.0, 1100.0)[None, :].repeat(64, 0)
    noisy = (clean + rng.normal(0, 5, clean.shape)).astype(np.uint16)
    out = preprocess.saint_marc(noisy, iterations=5)  # k from the image
    flat = np.s_[8:-8, 4:26]
    assert np.std(out[flat] - clean[flat]) < 0.4 * np.std(noisy[flat] - clean[flat])
    step = (out[8:-8, 32] - out[8:-8, 31]).mean()
    assert step > 95  # contrast across adjacent pixels kept
    blurred = ndimage.gaussian_filter(noisy.astype(float), 1.2)  # same noise reduction, no edges
    assert np.std(blurred[flat] - clean[flat]) < 0.4 * np.std(noisy[flat] - clean[flat])
    assert (blurred[8:-8, 32] - blurred[8:-8, 31]).mean() < 40


def test_pyramid_against_block_means_and_16bit_level0():
    img = sixteen_bit_image((50, 37), 3)
    levels = preprocess.pyramid(img, 4)
    assert [a.shape for a in levels] == [(50, 37), (17, 13), (6, 5), (2, 2)]
    assert all(a.dtype == np.float32 for a in levels)
    assert np.array_equal(levels[0], img.astype(np.float64)) and levels[0].max() > 255
    for lo, hi in zip(levels, levels[1:]):
        np.testing.assert_allclose(hi, block_mean_reference(lo.astype(np.float64), 3), rtol=1e-6)
    holes = img.astype(np.float32)
    holes[0:3, 0:3] = np.nan  # a whole block of nodata
    holes[4, 4] = np.nan
    level1 = preprocess.pyramid(holes, 2)[1]
    assert np.isnan(level1[0, 0]) and np.isfinite(level1).sum() == level1.size - 1
    np.testing.assert_allclose(level1, block_mean_reference(holes.astype(np.float64), 3), rtol=1e-6)


@pytest.mark.parametrize("level", [1, 2])
def test_pyramid_point_maps_to_to_level(level):
    # one lit full-resolution pixel: it falls in the level pixel containing to_level of its centre
    for r, c in [(0, 0), (40, 71), (80, 80), (13, 5)]:
        img = np.zeros((81, 83), np.float32)
        img[r, c] = 1000.0
        top = preprocess.pyramid(img, level + 1)[level]
        x, y = preprocess.to_level(c + 0.5, r + 0.5, level)
        assert np.unravel_index(np.argmax(top), top.shape) == (int(y), int(x))
    # a smooth blob at a sub-pixel position: its centroid in the level image is at to_level(x, y)
    x0, y0 = 41.3, 37.8
    yy, xx = np.mgrid[0:81, 0:81] + 0.5
    blob = np.exp(-((xx - x0) ** 2 + (yy - y0) ** 2) / (2 * 6.0**2))
    top = preprocess.pyramid(blob, level + 1)[level]
    ty, tx = np.mgrid[0 : top.shape[0], 0 : top.shape[1]] + 0.5
    centroid = (top * tx).sum() / top.sum(), (top * ty).sum() / top.sum()
    np.testing.assert_allclose(centroid, preprocess.to_level(x0, y0, level), atol=0.02)
    back = preprocess.from_level(*preprocess.to_level(np.array([x0, 0.0]), np.array([y0, 9.0]), level), level)
    np.testing.assert_allclose(back, [[x0, 0.0], [y0, 9.0]])
    assert preprocess.from_level(0.5, 0.5, 1) == (1.5, 1.5)  # level-1 pixel (0, 0): full-res (1, 1)


def test_levels_for():
    assert preprocess.levels_for(0) == 1
    assert preprocess.levels_for(4.0) == 1
    assert preprocess.levels_for(4.01) == 2
    assert preprocess.levels_for(12.0) == 2
    assert preprocess.levels_for(12.1) == 3
    assert preprocess.levels_for(100.0) == 4  # 100 / 27 = 3.7 px at the top
    assert preprocess.levels_for(100.0, 2.0, factor=2) == 7  # 100 / 64 = 1.6
    for rng_px in (1.0, 37.0, 500.0, 5000.0):
        n = preprocess.levels_for(rng_px, 3.0)
        assert rng_px / 3 ** (n - 1) <= 3.0 and (n == 1 or rng_px / 3 ** (n - 2) > 3.0)


def test_input_errors():
    img = np.zeros((10, 10))
    with pytest.raises(InputError, match="odd"):
        preprocess.wallis(img, window=4)
    with pytest.raises(InputError, match="contrast"):
        preprocess.wallis(img, contrast=0.0)
    with pytest.raises(InputError, match="2-D"):
        preprocess.saint_marc(np.zeros((3, 3, 3)))
    with pytest.raises(InputError, match="k must be"):
        preprocess.saint_marc(np.arange(100.0).reshape(10, 10), k=0.0)
    with pytest.raises(InputError, match="levels"):
        preprocess.pyramid(img, 0)
    with pytest.raises(InputError, match="factor"):
        preprocess.pyramid(img, 2, factor=1)
    with pytest.raises(InputError, match="parallax"):
        preprocess.levels_for(-1.0)
    assert np.array_equal(preprocess.saint_marc(np.full((5, 5), 7, np.uint16)), np.full((5, 5), 7.0))
