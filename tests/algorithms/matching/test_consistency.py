"""Forward-backward consistency (algorithms/matching/consistency.py) on a synthetic pair: image 2
is image 1 under a known affine map, so correct records come back to within a few hundredths of a
pixel and blundered ones by the size of their error."""

import numpy as np
import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.consistency import (
    back_guide,
    fb_summary,
    format_fb,
    forward_backward,
    invert_affine,
    observation_pairs,
)
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.matching.records import PAIR_DTYPE

A = np.array([[1.04, 0.03], [-0.02, 0.97]])  # image 1 -> image 2 (GDAL px), plus T
T = np.array([3.3, -2.6])
SIZE = 140
PARAMS = GrowParams(template=15)
HR = (0.0, 0.0)


class AffineModel:
    """Toy sensor model: ground (lon, lat) = M^-1 ((col, row) - t), heights ignored."""

    def __init__(self, m, t):
        self.m, self.t = np.asarray(m, float), np.asarray(t, float)
        self.minv = np.linalg.inv(self.m)
        self.height_range = HR

    def image_to_ground(self, col, row, h):
        p = np.stack([np.asarray(col, float) - self.t[0], np.asarray(row, float) - self.t[1]])
        g = np.tensordot(self.minv, p, 1)
        return g[0], g[1]

    def ground_to_image(self, lon, lat, h):
        g = np.stack([np.asarray(lon, float), np.asarray(lat, float)])
        p = np.tensordot(self.m, g, 1)
        return p[0] + self.t[0], p[1] + self.t[1]


@pytest.fixture(scope="module")
def pair():
    from scipy.ndimage import gaussian_filter, map_coordinates

    rng = np.random.default_rng(5)
    img1 = 100 + 400 * gaussian_filter(rng.standard_normal((SIZE, SIZE)), 1.5)
    # image 2 at GDAL position p2 shows image 1 at A^-1 (p2 - T)
    rows, cols = np.mgrid[0:SIZE, 0:SIZE]
    p1 = np.tensordot(np.linalg.inv(A), np.stack([cols + 0.5 - T[0], rows + 0.5 - T[1]]), 1)
    img2 = map_coordinates(img1, [p1[1] - 0.5, p1[0] - 0.5], order=3, mode="reflect")
    return img1.astype(np.float32), img2.astype(np.float32), AffineModel(np.eye(2), (0, 0)), AffineModel(A, T)


def true_records(with_affine=True):
    g = np.arange(25.5, SIZE - 30, 9.0)
    x1, y1 = (v.ravel() for v in np.meshgrid(g, g))
    x2, y2 = np.tensordot(A, np.stack([x1, y1]), 1) + T[:, None]
    rec = np.zeros(len(x1), PAIR_DTYPE)
    rec["x1"], rec["y1"], rec["x2"], rec["y2"] = x1, y1, x2, y2
    rec["rho"] = 0.9
    aff = A.ravel() if with_affine else np.full(4, np.nan)
    rec["a1"], rec["a2"], rec["a4"], rec["a5"] = aff
    return rec


def test_invert_affine_and_guide():
    b = invert_affine(*A.ravel())
    np.testing.assert_allclose(np.array(b).reshape(2, 2), np.linalg.inv(A))
    assert np.all(np.isnan(invert_affine(1.0, 2.0, 0.5, 1.0)))  # singular
    rec = true_records()
    guide = back_guide(rec)
    assert np.array_equal(guide["x1"], rec["x2"]) and np.array_equal(guide["x2"], rec["x1"])
    np.testing.assert_allclose(guide["a1"], np.linalg.inv(A)[0, 0], rtol=1e-6)
    # without an affine: the models' local affine image 2 -> image 1
    with pytest.raises(InputError):
        back_guide(true_records(with_affine=False))
    guide = back_guide(true_records(with_affine=False), AffineModel(np.eye(2), (0, 0)), AffineModel(A, T), 0.0)
    np.testing.assert_allclose(
        np.column_stack([guide[k] for k in ("a1", "a2", "a4", "a5")]),
        np.broadcast_to(np.linalg.inv(A).ravel(), (len(guide), 4)),
        atol=1e-5,
    )


@pytest.mark.parametrize("with_affine", [True, False], ids=["record-affine", "model-affine"])
@pytest.mark.parametrize("offset", [(0.0, 0.0), (0.6, -0.4)], ids=["from-original", "offset-start"])
def test_correct_matches_come_back(pair, with_affine, offset):
    img1, img2, m1, m2 = pair
    rec = true_records(with_affine)
    d = forward_backward(ImagePair(img1, img2, m1, m2), rec, PARAMS, HR, start_offset=offset)
    assert np.all(np.isfinite(d))
    s = fb_summary(d)
    assert s["rms"] < 0.03 and s["over"] == 0 and s["failed"] == 0, s


def test_blunders_show_their_size(pair):
    img1, img2, m1, m2 = pair
    rec = true_records()
    bad = np.arange(0, len(rec), 7)
    err = np.array([1.2, -0.8])
    rec["x2"][bad] += err[0]
    rec["y2"][bad] += err[1]
    d, back = forward_backward(ImagePair(img1, img2, m1, m2), rec, PARAMS, HR, return_records=True)
    # the image-2 template at x2 + e shows image 1 at x1 + A^-1 e
    expected = np.hypot(*(np.linalg.inv(A) @ err))
    np.testing.assert_allclose(d[bad], expected, atol=0.05)
    good = np.setdiff1d(np.arange(len(rec)), bad)
    assert np.nanmax(d[good]) < 0.05
    np.testing.assert_allclose(back["x1"], rec["x2"])  # image-2 templates
    s = fb_summary(d, threshold=1.0)
    assert s["over"] == pytest.approx(len(bad) / len(rec)) and s["rms"] > 0.4
    assert "back-matched" in format_fb("test", s)


def test_unusable_records_give_nan(pair):
    img1, img2, m1, m2 = pair
    rec = true_records()
    rec["x2"][3] = np.nan  # no image-2 position
    rec["x2"][5] = SIZE + 50.0  # template outside image 2
    d = forward_backward(ImagePair(img1, img2, m1, m2), rec, PARAMS, HR)
    assert np.isnan(d[3]) and np.isnan(d[5]) and np.isfinite(np.delete(d, [3, 5])).all()
    s = fb_summary(d)
    assert s["failed"] == 2 and s["back_matched"] == len(rec) - 2
    empty = forward_backward(ImagePair(img1, img2, m1, m2), np.zeros(0, PAIR_DTYPE), PARAMS, HR)
    assert empty.shape == (0,) and np.isnan(fb_summary(empty)["rms"])


def test_observation_pairs():
    points = np.zeros(3, POINT_DTYPE)
    points["id"], points["group"] = [1, 2, 3], [3, 1, 3]
    obs = np.zeros(8, OBS_DTYPE)
    obs["point_id"] = [1, 1, 1, 2, 2, 3, 3, 3]
    obs["image_id"] = [1, 2, 3, 1, 2, 1, 2, 3]
    obs["col"] = np.arange(8) * 10.0
    obs["row"] = np.arange(8) * 10.0 + 1
    obs["rho"] = 0.8
    mp = MultiPoints(points, obs)
    rec = observation_pairs(mp, 3, 2)
    assert list(rec["seed"]) == [1, 3]
    np.testing.assert_array_equal(rec["x1"], [20.0, 70.0])
    np.testing.assert_array_equal(rec["x2"], [10.0, 60.0])
    assert np.all(np.isnan(rec["a1"]))
    rec = observation_pairs(mp, 1, 2, which=points["group"] == 1)
    assert list(rec["seed"]) == [2] and rec["y1"][0] == 31.0 and rec["y2"][0] == 41.0
