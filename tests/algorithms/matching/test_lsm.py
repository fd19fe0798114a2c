"""Least-squares matching: kernels against plain numpy, precision calibration on simulated
band-limited texture, bad input."""

import numpy as np
import pytest
from scipy import ndimage

from pushbroom.algorithms import interpolation
from pushbroom.algorithms.matching import lsm
from pushbroom.algorithms.matching.params import TUKEY_C, GrowParams, LsmParams
from pushbroom.algorithms.matching.records import PAIR_DTYPE
from tests.helpers.texture import texture


def gn_step_reference(img1, img2, x1, y1, p, half, weights=None):
    """One Gauss-Newton step in plain numpy (same model and Jacobian as lsm_point), each equation weighted by
    `weights` (row-major over the template; None: 1). Returns (the parameters after it, rho, the residuals
    before it)."""
    x2, a1, a2, y2, a4, a5, r0, r1 = p
    k, l = np.meshgrid(np.arange(-half - 1, half + 2), np.arange(-half - 1, half + 2))
    t = ndimage.map_coordinates(img1.astype(float), [y1 + l - 0.5, x1 + k - 0.5], order=1)
    f = t[1:-1, 1:-1].ravel()
    fk = (0.5 * (t[1:-1, 2:] - t[1:-1, :-2])).ravel()
    fl = (0.5 * (t[2:, 1:-1] - t[:-2, 1:-1])).ravel()
    k, l = k[1:-1, 1:-1].ravel(), l[1:-1, 1:-1].ravel()
    xs, ys = x2 + a1 * k + a2 * l, y2 + a4 * k + a5 * l
    g = np.array([interpolation.cubic(img2, x, y)[0] for x, y in zip(xs, ys)])
    ia = np.linalg.inv(np.array([[a1, a2], [a4, a5]])).T
    rgx, rgy = ia @ np.vstack([fk, fl])
    a = np.column_stack([rgx, rgx * k, rgx * l, rgy, rgy * k, rgy * l, np.ones_like(g), g])
    v = f - (r0 + r1 * g)
    w = np.sqrt(np.ones_like(v) if weights is None else weights)
    dx = np.linalg.lstsq(a * w[:, None], v * w, rcond=None)[0]
    return np.asarray(p) + dx, np.corrcoef(f, g)[0, 1], v


def test_one_gauss_newton_step_against_numpy():
    rng = np.random.default_rng(2)
    tex = texture(rng)
    jj, ii = np.meshgrid(np.arange(40) + 0.5, np.arange(40) + 0.5)
    img1 = (100 + 30 * tex(jj, ii)).astype(np.float32)
    img2 = (5 + 1.1 * (100 + 30 * tex(0.98 * jj + 0.1 * ii - 0.4, ii * 1.02 + 0.7))).astype(np.float32)
    p = (20.2, 1.01, -0.05, 19.6, 0.02, 0.97, 0.0, 1.0)
    out = np.empty(lsm.LSM_OUT)
    status = lsm.lsm_point(
        img1, img2, 20.5, 20.5, lsm.Start(p[0], p[3], p[1], p[2], p[4], p[5]), lsm.Solver(7, 1, 1e-9), out
    )
    assert status == lsm.NOT_CONVERGED
    ref, rho, _ = gn_step_reference(img1, img2, 20.5, 20.5, p, 7)
    got = dict(zip(lsm.LSM_FIELDS, out))
    for name, value in zip(("x2", "a1", "a2", "y2", "a4", "a5", "r0", "r1"), ref):
        assert got[name] == pytest.approx(value, rel=1e-6, abs=1e-7), name
    assert got["rho"] == pytest.approx(rho, abs=1e-9)
    assert got["iterations"] == 1
    assert got["shift"] == pytest.approx(np.hypot(ref[0] - p[0], ref[3] - p[3]))


def simulate(n, m, gain, offset, noise, seed, size=33, init_scale=True, params=None):
    """n patch pairs: image 1 shows F at its pixel centres, image 2 pixel (x, y) shows
    gain * F(M (x, y) + t) + offset; both get white noise of sigma `noise`. Returns the LSM
    records, status and true image-2 positions of the image-1 centre (16.5, 16.5)."""
    rng = np.random.default_rng(seed)
    jj, ii = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    x1 = y1 = size / 2.0
    truth = np.empty((n, 2))
    recs, stats = [], []
    a0 = (1 / m[0, 0], 0.0, 0.0, 1 / m[1, 1]) if init_scale else (1.0, 0.0, 0.0, 1.0)
    for p in range(n):
        tex = texture(rng)
        img1 = (100 + 30 * tex(jj, ii) + rng.normal(0, noise, jj.shape)).astype(np.float32)
        truth[p] = size / 2.0 + rng.uniform(-0.5, 0.5, 2)
        t = np.array([x1, y1]) - m @ truth[p]
        xm = m[0, 0] * jj + m[0, 1] * ii + t[0]
        ym = m[1, 0] * jj + m[1, 1] * ii + t[1]
        img2 = (gain * (100 + 30 * tex(xm, ym)) + offset + rng.normal(0, noise, jj.shape)).astype(np.float32)
        init = truth[p] + rng.uniform(-1, 1, 2)
        rec, st = lsm.match_points(img1, img2, [x1], [y1], [init[0]], [init[1]], affine=a0, params=params)
        recs.append(rec[0])
        stats.append(st[0])
    return np.array(recs, dtype=PAIR_DTYPE), np.array(stats), truth


ROT = np.radians(10.0)
CASES = {
    "shift": (np.eye(2), 1.0, 0.0),
    "rotation 10 deg, gain 1.2, offset 10": (
        np.array([[np.cos(ROT), -np.sin(ROT)], [np.sin(ROT), np.cos(ROT)]]),
        1.2,
        10.0,
    ),
    "scale 2:1 along rows, gain 0.8, offset -5": (np.diag([1.0, 2.0]), 0.8, -5.0),
}


@pytest.mark.parametrize("case", list(CASES))
def test_precision_is_calibrated(case, figures):
    m, gain, offset = CASES[case]
    rec, status, truth = simulate(300, m, gain, offset, noise=4.0, seed=list(CASES).index(case) + 11)
    ok = status == 0
    assert ok.mean() > 0.95
    err = np.column_stack([rec["x2"] - truth[:, 0], rec["y2"] - truth[:, 1]])[ok]
    rms = np.sqrt((err**2).sum(1).mean())
    predicted = np.sqrt((rec["semi_major"][ok].astype(float) ** 2 + rec["semi_minor"][ok] ** 2).mean())
    ratio = rms / predicted
    figures.report("RMS error", rms, "px")
    figures.report("predicted (error ellipses)", predicted, "px")
    figures.report("ratio", ratio)
    assert 0.8 < ratio < 1.25
    assert rms < 0.1
    assert lsm.accepted(rec, status, LsmParams()).mean() > 0.9
    if case.startswith("scale"):
        assert np.median(rec["a5"][ok]) == pytest.approx(0.5, abs=0.01)
    if case.startswith("rotation"):
        assert np.median(rec["r1"][ok]) == pytest.approx(1 / 1.2, abs=0.02)


def test_rotation_from_identity_start():
    m = CASES["rotation 10 deg, gain 1.2, offset 10"][0]
    rec, status, truth = simulate(50, m, 1.2, 10.0, noise=2.0, seed=7, init_scale=False)
    ok = status == 0
    assert ok.mean() > 0.95
    assert np.abs(rec["a2"][ok] - np.linalg.inv(m)[0, 1]).max() < 0.02


def test_bad_input_statuses():
    rng = np.random.default_rng(3)
    img = (100 + 30 * ndimage.gaussian_filter(rng.normal(size=(40, 40)), 1.5)).astype(np.float32)
    out = np.empty(lsm.LSM_OUT)
    # window outside image 2 / image 1
    assert (
        lsm.lsm_point(img, img, 20.5, 20.5, lsm.Start(5.0, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.OUTSIDE
    )
    assert (
        lsm.lsm_point(img, img, 5.5, 20.5, lsm.Start(20.5, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.OUTSIDE
    )
    assert (
        lsm.lsm_point(img, img, 20.5, 20.5, lsm.Start(np.nan, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.OUTSIDE
    )
    # blank search image, blank template, NaN-filled image: singular, never an exception or a hang
    blank = np.full((40, 40), 7.0, np.float32)
    assert (
        lsm.lsm_point(img, blank, 20.5, 20.5, lsm.Start(20.5, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.SINGULAR
    )
    assert (
        lsm.lsm_point(blank, img, 20.5, 20.5, lsm.Start(20.5, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.SINGULAR
    )
    nan = np.full((40, 40), np.nan, np.float32)
    assert (
        lsm.lsm_point(nan, nan, 20.5, 20.5, lsm.Start(20.5, 20.5, 1.0, 0.0, 0.0, 1.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.SINGULAR
    )
    # degenerate affine
    assert (
        lsm.lsm_point(img, img, 20.5, 20.5, lsm.Start(20.5, 20.5, 0.0, 0.0, 0.0, 0.0), lsm.Solver(9, 10, 0.01), out)
        == lsm.SINGULAR
    )
    # the vectorised front end, with acceptance
    rec, status = lsm.match_points(img, blank, [20.5, 20.5], [20.5, 20.5], [20.5, 2.0], [20.5, 20.5])
    assert list(status) == [lsm.SINGULAR, lsm.OUTSIDE]
    assert not lsm.accepted(rec, status).any()
    rec, status = lsm.match_points(img, img, [20.5], [20.5], [20.9], [20.2])
    assert status[0] == 0 and lsm.accepted(rec, status)[0]
    assert rec["x2"][0] == pytest.approx(20.5, abs=1e-3) and rec["rho"][0] > 0.999


def test_match_points_input_errors():
    from pushbroom.algorithms.errors import InputError

    img = np.zeros((30, 30), np.float32)
    with pytest.raises(InputError):
        lsm.match_points(img, img, [1.0, 2.0], [1.0], [1.0], [1.0])
    with pytest.raises(InputError):
        lsm.match_points(img, img, [1.0], [1.0], [1.0], [1.0], params=LsmParams(template=4))
    with pytest.raises(InputError):
        lsm.match_points(np.zeros(30), img, [1.0], [1.0], [1.0], [1.0])


def other_surface(n, share, seed, params, size=41):
    """n patch pairs whose image 2 shows image 1's texture F shifted by a known sub-pixel offset, except the
    right `share` of the template's columns, which shows another surface (F shifted 3 px further along the
    columns: a canopy's parallax beside a field). Returns (records, status, truth) of LSM from 0.5 px off."""
    rng = np.random.default_rng(seed)
    jj, ii = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    c = size / 2.0
    half = params.template // 2
    edge = c + half + 0.5 - share * params.template  # image-2 columns right of it show the other surface
    recs, stats, truth = [], [], np.empty((n, 2))
    for p in range(n):
        tex = texture(rng)
        img1 = (100 + 30 * tex(jj, ii) + rng.normal(0, 2.0, jj.shape)).astype(np.float32)
        truth[p] = c + rng.uniform(-0.5, 0.5, 2)
        shift = np.where(jj > edge + truth[p, 0] - c, 3.0, 0.0)
        img2 = (
            100 + 30 * tex(jj - (truth[p, 0] - c) - shift, ii - (truth[p, 1] - c)) + rng.normal(0, 2.0, jj.shape)
        ).astype(np.float32)
        init = truth[p] + rng.uniform(-0.5, 0.5, 2)
        rec, st = lsm.match_points(img1, img2, [c], [c], [init[0]], [init[1]], params=params)
        recs.append(rec[0])
        stats.append(st[0])
    return np.array(recs, dtype=PAIR_DTYPE), np.array(stats), truth


def test_robust_weighting_resists_another_surface(figures):
    """A template with 15 % of another surface (the template reaching onto a canopy beside a field): plain
    least squares moves towards it, Tukey's weights keep to the field. (From a quarter on, both end between
    the two surfaces: lsm.py's docstring.)"""
    errors = {}
    for robust in (False, True):
        rec, status, truth = other_surface(60, 0.15, 5, GrowParams(template=19, robust=robust))
        ok = status == lsm.OK
        assert ok.mean() > 0.9
        errors[robust] = np.abs(rec["x2"] - truth[:, 0])[ok]
        figures.report(f"median |column error|, {'robust' if robust else 'plain'}", np.median(errors[robust]), "px")
    assert np.median(errors[False]) > 0.4  # pulled towards the other surface
    assert np.median(errors[True]) < 0.3 * np.median(errors[False])


def test_robust_step_against_numpy():
    """Two iterations of the robust LSM: the first unweighted, the second weighted by Tukey's biweight of each
    sample's residual against TUKEY_C times the RMS residual before the first; a template whose right columns
    show another surface, so that the weights range from under 0.5 to nearly 1."""
    rng = np.random.default_rng(4)
    tex = texture(rng)
    jj, ii = np.meshgrid(np.arange(40) + 0.5, np.arange(40) + 0.5)
    img1 = (100 + 30 * tex(jj, ii) + rng.normal(0, 2.0, jj.shape)).astype(np.float32)
    img2 = (100 + 30 * tex(jj - 0.3 - np.where(jj > 24.5, 3.0, 0.0), ii + 0.2)).astype(np.float32)
    p = (20.7, 1.0, 0.0, 20.4, 0.0, 1.0, 0.0, 1.0)
    out = np.empty(lsm.LSM_OUT)
    status = lsm.lsm_point(
        img1, img2, 20.5, 20.5, lsm.Start(p[0], p[3], p[1], p[2], p[4], p[5]), lsm.Solver(7, 2, 1e-9, TUKEY_C), out
    )
    assert status == lsm.NOT_CONVERGED
    first, _, v0 = gn_step_reference(img1, img2, 20.5, 20.5, p, 7)
    scale = TUKEY_C * np.sqrt(np.mean(v0**2))
    _, _, v1 = gn_step_reference(img1, img2, 20.5, 20.5, first, 7)
    u = v1 / scale
    weights = np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)
    assert weights.min() < 0.5 < 0.9 < weights.max()  # a weighting that matters
    ref, _, _ = gn_step_reference(img1, img2, 20.5, 20.5, first, 7, weights)
    got = dict(zip(lsm.LSM_FIELDS, out))
    for name, value in zip(("x2", "a1", "a2", "y2", "a4", "a5", "r0", "r1"), ref):
        assert got[name] == pytest.approx(value, rel=1e-6, abs=1e-7), name
    assert got["iterations"] == 2


def test_robust_precision_is_calibrated(figures):
    """On clean texture (no other surface) the weighted error ellipses still predict the error."""
    rec, status, truth = simulate(300, np.eye(2), 1.0, 0.0, noise=4.0, seed=11, params=GrowParams(robust=True))
    ok = status == lsm.OK
    assert ok.mean() > 0.95
    err = np.column_stack([rec["x2"] - truth[:, 0], rec["y2"] - truth[:, 1]])[ok]
    ratio = np.sqrt((err**2).sum(1).mean()) / np.sqrt(
        (rec["semi_major"][ok].astype(float) ** 2 + rec["semi_minor"][ok] ** 2).mean()
    )
    figures.report("RMS error / predicted, robust", ratio)
    assert 0.8 < ratio < 1.25


def test_the_wide_window_reports_its_ellipse_in_the_template_units():
    """match_accepted: a weak texture the 9 px template cannot pass (its ellipse beyond max_ellipse) matched with
    the 15 px window, whose ellipse is reported 15 / 9 times the one it measured (its acceptance on the measured
    one); the template's own matches keep theirs."""
    rng = np.random.default_rng(6)
    tex = texture(rng)
    jj, ii = np.meshgrid(np.arange(64) + 0.5, np.arange(64) + 0.5)
    img1 = (100 + 4 * tex(jj, ii) + rng.normal(0, 2.0, jj.shape)).astype(np.float32)
    img2 = (100 + 4 * tex(jj + 0.3, ii - 0.2) + rng.normal(0, 2.0, jj.shape)).astype(np.float32)
    x1 = y1 = np.full(1, 32.0)
    x2, y2 = x1 - 0.3 + 0.4, y1 + 0.2 - 0.3
    grow = GrowParams(template=9, wide_template=15, max_ellipse=0.12)
    narrow, status = lsm.match_points(img1, img2, x1, y1, x2, y2, params=grow)
    assert not lsm.accepted(narrow, status, grow)[0]
    wide = GrowParams(template=15, max_ellipse=0.12)
    measured, status = lsm.match_points(img1, img2, x1, y1, x2, y2, params=wide)
    assert lsm.accepted(measured, status, wide)[0]
    rec, ok = lsm.match_accepted(img1, img2, x1, y1, x2, y2, params=grow)
    assert ok[0] and rec["x2"][0] == measured["x2"][0]
    for axis in ("semi_major", "semi_minor"):
        assert rec[axis][0] == pytest.approx(measured[axis][0] * 15 / 9, rel=1e-6)
    plain, ok = lsm.match_accepted(img1, img2, x1, y1, x2, y2, params=wide)
    assert ok[0] and plain["semi_major"][0] == measured["semi_major"][0]
