"""Census, cost, winner and left-right kernels against plain numpy; the whole disparity on a pair with a
known disparity field; an image without texture gives no disparity."""
import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms.dense import sgm


def texture(rows, cols, seed=1):
    rng = np.random.default_rng(seed)
    return ndimage.gaussian_filter(rng.normal(size=(rows, cols)), 1.2) * 50 + 100


def test_census_against_numpy():
    img = texture(12, 15).astype(np.float32)
    img[6, 9] = np.nan
    img[:5, :5] = 50.0                          # a flat window: no code at (2, 2)
    codes, valid = sgm.census(img, 2)
    for i in range(12):
        for j in range(15):
            win = img[max(i - 2, 0):i + 3, max(j - 2, 0):j + 3]
            expect_valid = 2 <= i < 10 and 2 <= j < 13 and np.isfinite(win).all() and np.ptp(win) > 0
            assert valid[i, j] == expect_valid
            if expect_valid:
                bits = np.delete((win < img[i, j]).ravel(), 12)
                assert int(codes[i, j]) == int("".join("1" if b else "0" for b in bits), 2)


def test_cost_winner_and_lr_against_numpy():
    rng = np.random.default_rng(2)
    c1 = rng.integers(0, 2 ** 24, (6, 20)).astype(np.uint64)
    c2 = rng.integers(0, 2 ** 24, (6, 25)).astype(np.uint64)
    v1, v2 = rng.random((6, 20)) > 0.1, rng.random((6, 25)) > 0.1
    cv = np.empty((6, 20, 7), np.float32)
    sgm.cost_kernel(c1, v1, c2, v2, -2, np.float32(57.0), cv)
    for i, j, k in np.ndindex(cv.shape):
        j2 = j - 2 + k
        ok = v1[i, j] and 0 <= j2 < 25 and v2[i, j2]
        assert cv[i, j, k] == (bin(int(c1[i, j]) ^ int(c2[i, j2])).count("1") if ok else 57.0)
    s = (rng.random((6, 20, 7)) * 50).astype(np.float32)
    s[0, 0] = 1000.0                                          # no valid cost
    s[0, 1] = 5.0                                             # flat: nothing to choose
    disp, cost = np.empty((6, 20), np.float32), np.empty((6, 20), np.float32)
    sgm.winner_kernel(s, -2, np.float32(500.0), disp, cost)
    k = s.argmin(axis=2)
    assert np.isnan(disp[0, :2]).all()
    for i, j in np.ndindex(disp.shape):
        if (i, j) in ((0, 0), (0, 1)):
            continue
        b = k[i, j]
        delta = 0.0
        if 0 < b < 6:
            cm, c0, cp = s[i, j, b - 1], s[i, j, b], s[i, j, b + 1]
            delta = (cm - cp) / (2 * max(cm - c0, cp - c0))
        assert disp[i, j] == pytest.approx(-2 + b + delta, abs=1e-5)
        assert cost[i, j] == s[i, j, b]
    disp2 = np.empty((6, 25), np.float32)
    sgm.right_kernel(s, -2, np.float32(500.0), 25, disp2)
    for i, j2 in np.ndindex(disp2.shape):
        cands = [(s[i, j2 - d, d + 2], d) for d in range(-2, 5) if 0 <= j2 - d < 20 and s[i, j2 - d, d + 2] < 500]
        assert (np.isnan(disp2[i, j2]) if not cands else disp2[i, j2] == min(cands)[1])
    checked = disp.copy()
    sgm.lr_check_kernel(checked, disp2, np.float32(1.0))
    for i, j in np.ndindex(disp.shape):
        d = disp[i, j]
        j2 = int(np.floor(j + d + 0.5)) if np.isfinite(d) else -1
        keep = np.isfinite(d) and 0 <= j2 < 25 and abs(disp2[i, j2] - d) <= 1.0
        assert np.isfinite(checked[i, j]) == keep


def shifted_pair(rows=160, cols=240):
    """image 2 (u + d(u), v) = image 1 (u, v), d = 5.3 + 0.01 u: both sampled from one texture by
    cubic splines."""
    base = texture(rows, cols + 60)
    u = np.arange(cols, dtype=float)
    x2 = np.arange(cols + 40, dtype=float)
    v = np.arange(rows, dtype=float)[:, None]
    img1 = ndimage.map_coordinates(base, [v + 0 * u, u + 20 + 0 * v], order=3)
    img2 = ndimage.map_coordinates(base, [v + 0 * x2, (x2 - 5.3) / 1.01 + 20 + 0 * v], order=3)
    return img1.astype(np.float32), img2.astype(np.float32), 5.3 + 0.01 * u + 0 * v


def test_disparity_of_a_known_field(figures):
    img1, img2, truth = shifted_pair()
    disp = sgm.disparity(img1, img2, (-5, 20))
    err = np.abs(disp - truth)
    figures.report("SGM on a known disparity field, valid", np.isfinite(disp).mean() * 100, "%",
                   f"median |error| {np.nanmedian(err):.3f} px, 99th percentile {np.nanpercentile(err, 99):.3f} px")
    assert np.isfinite(disp[3:-3, 3:-3]).mean() > 0.95
    assert np.nanmedian(err) < 0.2 and np.nanpercentile(err, 99) < 0.6


def test_no_texture_gives_no_disparity():
    flat = np.full((40, 60), 80.0, np.float32)
    disp = sgm.disparity(flat, flat, (-4, 4))
    assert np.isnan(disp).all()
