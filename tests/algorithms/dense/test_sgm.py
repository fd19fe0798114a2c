"""Census, cost, winner and left-right kernels against plain numpy; the whole disparity on a pair with a
known disparity field; an image without texture gives no disparity; where image 2 is masked, no disparity
whose conjugate may be a candidate without a code (the scored candidates' rule, against a loop and on a
hand-made case)."""

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
    img[:5, :5] = 50.0  # a flat window: no code at (2, 2)
    codes, valid = sgm.census(img, 2)
    for i in range(12):
        for j in range(15):
            win = img[max(i - 2, 0) : i + 3, max(j - 2, 0) : j + 3]
            expect_valid = 2 <= i < 10 and 2 <= j < 13 and np.isfinite(win).all() and np.ptp(win) > 0
            assert valid[i, j] == expect_valid
            if expect_valid:
                bits = np.delete((win < img[i, j]).ravel(), 12)
                assert int(codes[i, j]) == int("".join("1" if b else "0" for b in bits), 2)


def test_cost_winner_and_lr_against_numpy():
    rng = np.random.default_rng(2)
    c1 = rng.integers(0, 2**24, (6, 20)).astype(np.uint64)
    c2 = rng.integers(0, 2**24, (6, 25)).astype(np.uint64)
    v1, v2 = rng.random((6, 20)) > 0.1, rng.random((6, 25)) > 0.1
    cv = np.empty((6, 20, 7), np.float32)
    sgm.cost_kernel(c1, v1, c2, v2, -2, np.float32(57.0), cv)
    for i, j, k in np.ndindex(cv.shape):
        j2 = j - 2 + k
        ok = v1[i, j] and 0 <= j2 < 25 and v2[i, j2]
        assert cv[i, j, k] == (bin(int(c1[i, j]) ^ int(c2[i, j2])).count("1") if ok else 57.0)
    s = (rng.random((6, 20, 7)) * 50).astype(np.float32)
    s[0, 0] = 1000.0  # no valid cost
    s[0, 1] = 5.0  # flat: nothing to choose
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
        assert np.isnan(disp2[i, j2]) if not cands else disp2[i, j2] == min(cands)[1]
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
    figures.report(
        "SGM on a known disparity field, valid",
        np.isfinite(disp).mean() * 100,
        "%",
        f"median |error| {np.nanmedian(err):.3f} px, 99th percentile {np.nanpercentile(err, 99):.3f} px",
    )
    assert np.isfinite(disp[3:-3, 3:-3]).mean() > 0.95
    assert np.nanmedian(err) < 0.2 and np.nanpercentile(err, 99) < 0.6


def test_no_texture_gives_no_disparity():
    flat = np.full((40, 60), 80.0, np.float32)
    disp = sgm.disparity(flat, flat, (-4, 4))
    assert np.isnan(disp).all()


def candidates_scored(v1, v2, lo, hi):
    """sgm's test of scored candidates (its _scored on image 2's missing codes) for every image-1 pixel."""
    i, j = np.indices(v1.shape)
    return v1 & sgm._scored(sgm._missing_codes(v2), i, j, lo, hi)


def test_candidates_scored_against_a_loop():
    rng = np.random.default_rng(3)
    v1, v2 = rng.random((5, 30)) > 0.1, rng.random((5, 34)) > 0.05
    per_pixel = rng.integers(-4, 3, (5, 30)), rng.integers(0, 6, (5, 30))
    for lo, hi in ((-3, 4), (0, 0), (2, 9), per_pixel):
        got = candidates_scored(v1, v2, lo, hi)
        for i, j in np.ndindex(v1.shape):
            a, b = (int(v[i, j]) if np.ndim(v) else v for v in (lo, hi))
            assert got[i, j] == (v1[i, j] and all(0 <= j + d < 34 and v2[i, j + d] for d in range(a, b + 1)))


def test_a_disparity_bounded_by_its_surface_or_none():
    """Image 2 has no code at columns 20 ... 24; the surface's disparity is 5 over the range 0 ... 10. A pixel whose
    candidates all have a code keeps its disparity; the others only where the kept disparities around them
    (LOCAL_RADIUS 3 px), widened by LOCAL_SLACK 3 px, bound theirs and every candidate between those bounds has a
    code: j = 10 and 11 (candidates up to 18 and 19), then none up to j = 22 (its bounds reach column 24), and
    from j = 23 on (candidates from 25). Pixel 11's disparity 9 is beyond its bounds 2 ... 8; pixel 16's 2, a
    mismatch (its conjugate 21 has no code), has no kept pixel near it."""
    v1, v2 = np.ones((7, 40), bool), np.ones((7, 50), bool)
    v2[:, 20:25] = False
    disp = np.full((7, 40), 5.0, np.float32)
    disp[:, 16] = 2.0
    kept = np.isfinite(sgm.scored_disparities(disp, v1, v2, 0, 10))
    assert (kept == ((np.arange(40) <= 11) | (np.arange(40) >= 23))[None, :]).all()
    disp[:, 11] = 9.0
    kept = np.isfinite(sgm.scored_disparities(disp, v1, v2, 0, 10))
    assert (kept == ((np.arange(40) <= 10) | (np.arange(40) >= 23))[None, :]).all()


def test_masked_image_2_gives_no_wrong_disparity():
    """Image 2 with a nodata band across the rows and a masked patch: the pixels whose conjugates fall there
    used to take the best of the other candidates (up to 14 px off); now every kept disparity is right, and the
    pixels lost are those whose conjugate is masked, within a margin."""
    img1, img2, truth = shifted_pair()
    img2[:, 100:130] = np.nan
    img2[60:90, 160:200] = np.nan
    d_range = (-5, 20)
    disp = sgm.disparity(img1, img2, d_range)
    kept = np.isfinite(disp)
    # the truth's error where kept: as on the clean pair (test_disparity_of_a_known_field)
    assert np.abs(disp - truth)[kept].max() < 1.0
    # no kept pixel's conjugate lies within the census window (2 px) of a masked image-2 pixel
    masked = ndimage.binary_dilation(np.isnan(img2), np.ones((5, 5), bool))
    rows, cols = np.nonzero(kept)
    assert not masked[rows, np.rint(cols + disp[kept]).astype(int)].any()
    # the others are matched as on the clean pair, up to LOCAL_SLACK + 2 px (and the census window) from the
    # conjugates of the masked pixels; the clean pair keeps more than 95 % of its pixels
    conjugate = np.rint(np.arange(240) + truth[0]).astype(int)
    clear = ~ndimage.binary_dilation(masked[:, conjugate], np.ones((5, 2 * (int(sgm.LOCAL_SLACK) + 2) + 1), bool))
    clear[:3] = clear[-3:] = False
    clear[:, :8] = clear[:, -3:] = False  # image 1's edge, and candidates before image 2's
    assert kept[clear].mean() > 0.95
