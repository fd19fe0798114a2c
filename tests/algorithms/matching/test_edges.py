"""Canny edges, linking and edgel matching with the figural continuity constraint (algorithms/matching/
edges.py): kernels against numpy/scipy references, edges of synthetic shapes against their analytic
outlines, and edge matching on a synthetic stereo pair with a known height field (a sloping plane
with a raised flat roof) and injected look-alike repeats."""

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching import edges, edges_kernels as kernels

# --------------------------------------------------------------------------------------------
# references (plain numpy / scipy)


def nms_reference(gx, gy, mag, allowed):
    """Interpolated non-maximum suppression, vectorised (same rule as kernels.nms)."""
    nr, nc = mag.shape
    i, j = np.mgrid[1 : nr - 1, 1 : nc - 1]
    gxi, gyi, m = gx[i, j], gy[i, j], mag[i, j]
    ax, ay = np.abs(gxi), np.abs(gyi)
    sx = np.where(gxi >= 0, 1, -1)
    sy = np.where(gyi >= 0, 1, -1)
    xdom = ax >= ay
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(xdom, ay / ax, ax / ay)
    w = np.nan_to_num(w)
    main_i = np.where(xdom, i, i + sy)
    main_j = np.where(xdom, j + sx, j)
    back_i = np.where(xdom, i, i - sy)
    back_j = np.where(xdom, j - sx, j)
    ahead = (1.0 - w) * mag[main_i, main_j] + w * mag[i + sy, j + sx]
    behind = (1.0 - w) * mag[back_i, back_j] + w * mag[i - sy, j - sx]
    out = np.zeros(mag.shape, bool)
    out[1:-1, 1:-1] = allowed[i, j] & (m > 0) & (m > behind) & (m >= ahead)
    return out


def hysteresis_reference(weak, strong):
    labels, n = ndimage.label(weak, structure=np.ones((3, 3), int))
    keep = np.zeros(n + 1, bool)
    keep[np.unique(labels[strong & weak])] = True
    keep[0] = False
    return keep[labels]


def noisy(img, std, seed):
    return img + np.random.default_rng(seed).normal(0.0, std, img.shape)


def step_image(shape=(100, 120), col=60, contrast=100.0):
    img = np.zeros(shape)
    img[:, col:] = contrast
    return img


def disc_image(size=200, centre=(100.0, 90.0), radius=50.0, contrast=80.0, sub=4):
    """A bright disc, area-sampled (sub x sub samples per pixel)."""
    o = (np.arange(sub) + 0.5) / sub
    y, x = np.mgrid[:size, :size]
    acc = np.zeros((size, size))
    for dy in o:
        for dx in o:
            acc += (x + dx - centre[0]) ** 2 + (y + dy - centre[1]) ** 2 < radius**2
    return contrast * acc / sub**2


# --------------------------------------------------------------------------------------------
# Canny


def test_nms_and_hysteresis_kernels_match_numpy():
    rng = np.random.default_rng(1)
    img = ndimage.gaussian_filter(rng.normal(size=(90, 110)), 1.5) * 50 + disc_image(110)[:90]
    gx, gy, ok = edges.gradients(img, 1.0)
    mag = np.hypot(gx, gy)
    ok[10:20, 30:50] = False
    got = np.empty(mag.shape, bool)
    kernels.nms(gx, gy, mag, ok, got)
    want = nms_reference(gx, gy, mag, ok)
    assert got.sum() > 500 and np.array_equal(got, want)
    low, high = np.percentile(mag[got], [30, 80])
    weak, strong = got & (mag >= low), got & (mag >= high)
    out = np.empty(mag.shape, bool)
    kernels.hysteresis(weak, strong, out)
    assert strong.sum() < out.sum() < weak.sum()
    assert np.array_equal(out, hysteresis_reference(weak, strong))


def test_gradients_sign_and_scale_on_a_ramp():
    y, x = np.mgrid[:40, :50]
    gx, gy, ok = edges.gradients(2.0 * x - 0.5 * y + 3.0, 1.0)
    inner = np.s_[6:-6, 6:-6]
    assert np.allclose(gx[inner], 2.0) and np.allclose(gy[inner], -0.5)
    assert ok[1:-1, 1:-1].all() and not ok[0].any() and not ok[:, -1].any()


def test_noise_std_is_recovered_next_to_edges():
    img = noisy(step_image() + disc_image(120)[:100], 3.0, 2)
    assert edges.noise_std(img) == pytest.approx(3.0, rel=0.1)


def test_canny_finds_a_noisy_step_within_one_pixel():
    img = noisy(step_image(col=60), 3.0, 0)  # the step is at x = 60.0
    e = edges.canny(img)
    r, c = np.nonzero(e)
    assert np.all(np.abs(c + 0.5 - 60.0) <= 1.0), "no edge pixel away from the step"
    assert np.unique(r).size >= 96  # rows 1..98 (the border is never an edge)


def test_canny_finds_a_noisy_disc_within_one_pixel():
    img = noisy(disc_image(), 4.0, 3)
    e = edges.canny(img, sigma=1.5)
    r, c = np.nonzero(e)
    dist = np.hypot(c + 0.5 - 100.0, r + 0.5 - 90.0) - 50.0
    assert np.abs(dist).max() <= 1.0
    angle = np.degrees(np.arctan2(r + 0.5 - 90.0, c + 0.5 - 100.0))
    assert np.unique(np.floor(angle / 2.0)).size == 180  # every 2 degrees of the outline is found


def test_canny_with_nodata_and_explicit_thresholds():
    img = noisy(step_image(col=60), 1.0, 4)
    img[:, :30] = np.nan  # nodata: no edge along its border
    img[40:45, 58:62] = np.nan
    e = edges.canny(img, low=5.0, high=10.0)
    r, c = np.nonzero(e)
    assert np.all(np.abs(c + 0.5 - 60.0) <= 1.0)
    assert not e[39:46, 57:63].any() and not e[:, :31].any() and e[36:49].any()
    assert not edges.canny(img, low=200.0, high=300.0).any()
    with pytest.raises(InputError, match="low <= high"):
        edges.canny(img, low=3.0, high=2.0)
    with pytest.raises(InputError, match="2-D"):
        edges.canny(np.zeros(10))


# --------------------------------------------------------------------------------------------
# linking


def test_link_one_chain_along_the_step():
    chains = edges.link(edges.canny(noisy(step_image(col=60), 3.0, 0)))
    assert len(chains) == 1
    c = chains[0]
    assert c.dtype == np.float64 and c.shape[1] == 2 and len(c) >= 96
    assert np.all(np.abs(c[:, 0] - 60.0) <= 1.0)
    steps = np.abs(np.diff(c, axis=0))
    assert np.all(steps.max(axis=1) == 1.0)  # 8-connected, ordered
    assert np.ptp(c[:, 1]) >= 95


def test_link_one_closed_chain_around_the_disc():
    chains = edges.link(edges.canny(noisy(disc_image(), 4.0, 3), sigma=1.5))
    assert len(chains) == 1
    c = chains[0]
    assert np.all(np.abs(np.hypot(c[:, 0] - 100.0, c[:, 1] - 90.0) - 50.0) <= 1.0)
    steps = np.abs(np.diff(np.vstack([c, c[:1]]), axis=0))
    assert np.all(steps.max(axis=1) == 1.0)  # closed: the last point neighbours the first
    assert 2 * np.pi * 50 / 1.42 < len(c) < 2 * np.pi * 50


def test_link_splits_junctions_and_drops_short_chains():
    m = np.zeros((60, 60), bool)
    m[30, 5:55] = True  # a horizontal line ...
    m[5:30, 20] = True  # ... with a branch from above (T junction at (30, 20))
    m[45:50, 40] = True  # a short isolated piece (5 px)
    for k in range(12):  # a staircase diagonal (redundant corners), no junction
        m[40 + k // 2, 5 + k] = True
    chains = edges.link(m, min_length=6)
    lengths = sorted(len(c) for c in chains)
    # the T's corner pixel (30, 20) is a simple point and goes: the junction is (29, 20); arms of 24,
    # 15 and 34 pixels, each + the junction; the diagonal (two pixels per step) has no junction
    assert lengths == [12, 16, 25, 35], lengths
    ends = [tuple(c[0]) for c in chains] + [tuple(c[-1]) for c in chains]
    assert ends.count((20.5, 29.5)) == 3  # the three arms meet on the junction pixel
    assert len(edges.link(m, min_length=5)) == 5 and edges.link(np.zeros((5, 5))) == []


def path_cost(choice, index, step, ncand, d, cost, jump_cost, jump_tol, skip_cost, max_skip):
    """Total cost of one assignment of a chain (the objective kernels.figural_dp minimises); inf if invalid."""
    live = np.flatnonzero(ncand > 0)
    chosen = [e for e in live if choice[e] >= 0]
    if not chosen:
        return np.inf
    total = skip_cost * (live.size - len(chosen)) + sum(cost[e, choice[e]] for e in chosen)
    pos = {e: k for k, e in enumerate(live)}
    for a, b in zip(chosen[:-1], chosen[1:]):
        if pos[b] - pos[a] - 1 > max_skip:
            return np.inf
        jump = abs(d[b, choice[b]] - d[a, choice[a]]) - jump_tol * (index[b] - index[a]) / step
        total += jump_cost * max(jump, 0.0)
    return total


def test_figural_dp_finds_the_least_cost_sequence():
    rng = np.random.default_rng(11)
    args = (0.5, 0.5, 0.4, 2)  # jump_cost, jump_tol, skip_cost, max_skip
    for trial in range(40):
        n, kmax = 6, 3
        ncand = rng.integers(0, kmax + 1, n)
        d = np.where(np.arange(kmax) < ncand[:, None], rng.uniform(0, 6, (n, kmax)), np.nan)
        cost = np.where(np.isfinite(d), rng.uniform(0, 0.6, (n, kmax)), np.nan)
        index = np.arange(n) * 2
        choice = np.empty(n, np.int64)
        kernels.figural_dp(np.array([0, n]), index, 2.0, ncand, d, cost, *args, choice)
        options = [range(-1, k) for k in ncand]
        best = min(
            path_cost(np.array(c), index, 2.0, ncand, d, cost, *args)
            for c in np.array(np.meshgrid(*options, indexing="ij")).reshape(n, -1).T
        )
        got = path_cost(choice, index, 2.0, ncand, d, cost, *args)
        assert (choice < ncand).all()
        if np.isinf(best):
            assert (choice == -1).all()
        else:
            assert got == pytest.approx(best, abs=1e-12), trial


# --------------------------------------------------------------------------------------------
# edge matching: a synthetic stereo pair

K_COL, K_ROW = 0.05, 0.0025  # px of parallax per metre of height (search = ref + K h)
H_RANGE = (-50.0, 450.0)
ROOF = (60.0, 120.0, 40.0, 110.0)  # x0, x1, y0, y1 of a flat roof, ROOF_H above the plane
ROOF_H = 100.0
ROAD = (180.0, 184.0)  # a dark vertical road at these x
REPEAT_ROWS = (60, 110)  # search-image rows where a look-alike copy of the road is pasted ...
REPEAT_SHIFT = (20, 1)  # ... shifted by these (cols, rows): the height 400 m


def predict(col, row, h):
    return col + K_COL * h, row + K_ROW * h


def plane(x, y):
    return 120.0 + 0.2 * (x - 110.0) + 0.1 * (y - 80.0)


def in_roof(x, y):
    return (x >= ROOF[0]) & (x < ROOF[1]) & (y >= ROOF[2]) & (y < ROOF[3])


def true_height(x, y):
    """Height of the surface an edgel at (x, y) belongs to: the roof outline (within 1.5 px) is the roof's."""
    near = (x > ROOF[0] - 1.5) & (x < ROOF[1] + 1.5) & (y > ROOF[2] - 1.5) & (y < ROOF[3] + 1.5)
    return plane(x, y) + np.where(near, ROOF_H, 0.0)


def scene_pair(shape=(150, 230), seed=7, noise=2.0, sub=3):
    """(ref, search): ref = the ground texture seen from above; search = the same seen with parallax
    K h (plane + roof; the roof hides the ground it covers, walls are uniform grey 70)."""
    rng = np.random.default_rng(seed)
    pad = 40
    tex = ndimage.gaussian_filter(rng.normal(size=(shape[0] + 2 * pad, shape[1] + 2 * pad)), 2.0)
    tex *= 6.0 / tex.std()

    def albedo(x, y):
        g = 100.0 + ndimage.map_coordinates(tex, [y - 0.5 + pad, x - 0.5 + pad], order=1, mode="nearest")
        g += 50.0 * ((x - 170.0) ** 2 + (y - 40.0) ** 2 < 18.0**2)  # a bright disc on the ground
        g -= 45.0 * ((x >= ROAD[0]) & (x < ROAD[1]))
        return np.where(in_roof(x, y), 160.0 + 0.5 * (g - 100.0), g)

    o = (np.arange(sub) + 0.5) / sub
    yy, xx = np.mgrid[: shape[0], : shape[1]].astype(float)
    ref = np.zeros(shape)
    search = np.zeros(shape)
    m = np.array([[1 + K_COL * 0.2, K_COL * 0.1], [K_ROW * 0.2, 1 + K_ROW * 0.1]])  # (x, y) -> (x2, y2) linear part
    minv = np.linalg.inv(m)
    h0 = 120.0 - 0.2 * 110.0 - 0.1 * 80.0
    for dy in o:
        for dx in o:
            x, y = xx + dx, yy + dy
            ref += albedo(x, y)
            ground = []
            for extra in (ROOF_H, 0.0):
                bx, by = x - K_COL * (h0 + extra), y - K_ROW * (h0 + extra)
                ground.append((minv[0, 0] * bx + minv[0, 1] * by, minv[1, 0] * bx + minv[1, 1] * by))
            (rx, ry), (gx, gy) = ground
            roof = in_roof(rx, ry)
            wall = ~roof & in_roof(gx, gy)
            search += np.where(roof, albedo(rx, ry), np.where(wall, 70.0, albedo(gx, gy)))
    ref, search = ref / sub**2, search / sub**2
    clean_ref = ref.copy()
    ref = noisy(ref, noise, seed + 1)
    search = noisy(search, noise, seed + 2)
    return ref, search, clean_ref


def errors_px(rec):
    """Distance (px) of each matched edgel from its true search position."""
    tx, ty = predict(rec["col"], rec["row"], true_height(rec["col"], rec["row"]))
    return np.hypot(rec["col2"] - tx, rec["row2"] - ty)


@pytest.fixture(scope="module")
def pair():
    ref, search, _ = scene_pair()
    chains = edges.link(edges.canny(ref, sigma=1.0), min_length=15)
    return ref, search, chains


def test_predict_and_rendering_agree_on_the_ground():
    ref, search, _ = scene_pair(noise=0.0)
    x, y = 20.5, 130.5
    x2, y2 = predict(x, y, plane(x, y))
    # a textured ground window moved by the predicted parallax correlates
    f = ref[125:137, 15:27]
    g = ndimage.map_coordinates(search, np.mgrid[125:137, 15:27] + np.array([y2 - y, x2 - x])[:, None, None], order=1)
    assert np.corrcoef(f.ravel(), g.ravel())[0, 1] > 0.99


@pytest.mark.ratchet
def test_match_edges_recovers_the_disparity(pair, figures):
    ref, search, chains = pair
    rec = edges.match_edges(ref, search, chains, predict, H_RANGE)
    assert rec.dtype == edges.EDGEL_DTYPE and rec.size == sum((len(c) + 1) // 2 for c in chains)
    ok = rec["ok"]
    err = errors_px(rec[ok])
    within = np.mean(err <= 0.5)
    gx, gy, _ = edges.gradients(ref)
    i, j = rec["row"].astype(int), rec["col"].astype(int)
    crossing = np.abs(gx[i, j] * K_COL + gy[i, j] * K_ROW) / (np.hypot(gx[i, j], gy[i, j]) * np.hypot(K_COL, K_ROW))
    matchable = crossing > np.sin(np.radians(35.0))  # edges >= 35 degrees from parallel to the epipolar line
    roof = ok & (np.abs(true_height(rec["col"], rec["row"]) - plane(rec["col"], rec["row"])) > 1)
    roof_within = np.mean(errors_px(rec[roof]) <= 0.5)
    figures.report("edgels", rec.size)
    figures.report("ok", 100 * ok.mean(), "%")
    figures.report("edgels >= 35 degrees from the epipolar direction", matchable.sum())
    figures.report("of those ok", 100 * ok[matchable].mean(), "%")
    figures.report("|error| <= 0.5 px", 100 * within, "%")
    figures.report("roof outline edgels ok", roof.sum())
    figures.report("of those |error| <= 0.5 px", 100 * roof_within, "%")
    figures.report("median error", np.median(err), "px")
    figures.report("error > 2 px", 100 * np.mean(err > 2), "%")
    assert ok[matchable].mean() > 0.8 and within > 0.9 and np.mean(err > 2) < 0.02
    assert roof.sum() > 50 and roof_within > 0.9
    h = rec["h"][ok]
    assert np.median(np.abs(h - true_height(rec["col"][ok], rec["row"][ok]))) < 3.0  # m (0.15 px)


def test_figural_continuity_removes_injected_repeats(pair, figures):
    ref, search, chains = pair
    # a look-alike of the road: the reference's own pixels pasted next to the true road
    fake = search.copy()
    r0, r1 = REPEAT_ROWS
    sx, sy = REPEAT_SHIFT
    c0, c1 = int(ROAD[0]) - 6, int(ROAD[1]) + 6
    fake[r0 + sy : r1 + sy, c0 + sx : c1 + sx] = ref[r0:r1, c0:c1]
    plain = edges.match_edges(ref, fake, chains, predict, H_RANGE, edges.EdgeMatching(figural=False))
    figural = edges.match_edges(ref, fake, chains, predict, H_RANGE)
    road = (np.abs(plain["col"] - ROAD[0]) < 1.5) | (np.abs(plain["col"] - ROAD[1]) < 1.5)
    inside = road & (plain["row"] >= r0 + 4) & (plain["row"] < r1 - 4)
    assert inside.sum() >= 30
    wrong_plain = np.mean(~(errors_px(plain[inside & plain["ok"]]) <= 1.0))
    wrong_figural = np.mean(~(errors_px(figural[inside & figural["ok"]]) <= 1.0))
    kept = np.mean(figural["ok"][inside])
    figures.report("road edgels among the repeats", inside.sum())
    figures.report("wrong (> 1 px), plain best NCC", 100 * wrong_plain, "%", f"of {np.sum(inside & plain['ok'])} ok")
    figures.report(
        "wrong (> 1 px), figural continuity", 100 * wrong_figural, "%", f"of {np.sum(inside & figural['ok'])} ok"
    )
    assert wrong_plain > 0.5 and wrong_figural < 0.05 and kept > 0.8


def test_match_edges_input_errors(pair):
    ref, search, chains = pair
    with pytest.raises(InputError, match="h_max > h_min"):
        edges.match_edges(ref, search, chains, predict, (10.0, 10.0))
    with pytest.raises(InputError, match="odd"):
        edges.match_edges(ref, search, chains, predict, H_RANGE, edges.EdgeMatching(window=6))
    with pytest.raises(InputError, match=r"\(n, 2\)"):
        edges.match_edges(ref, search, [np.zeros(5)], predict, H_RANGE)
    per_point = [np.full(sum(map(len, chains)), v) for v in H_RANGE]  # one range per chain point
    a = edges.match_edges(ref, search, chains[:5], predict, H_RANGE)
    b = edges.match_edges(ref, search, chains[:5], predict, [p[: sum(map(len, chains[:5]))] for p in per_point])
    assert a["ok"].any()
    for name in a.dtype.names:
        np.testing.assert_array_equal(a[name], b[name])  # NaN == NaN here
    with pytest.raises(InputError, match="one value per"):
        edges.match_edges(ref, search, chains, predict, [p[:10] for p in per_point])
    empty = edges.match_edges(ref, search, [], predict, H_RANGE)
    assert empty.size == 0
    nan = np.full_like(search, np.nan)
    rec = edges.match_edges(ref, nan, chains[:2], predict, H_RANGE)
    assert not rec["ok"].any() and np.isnan(rec["col2"]).all()
