"""Acceptance of the dense matching on real pixels (issue: region-growing LSM, three images): on the
Pleiades triplet of the real test data (pleiades_triplet: RPC, 0.5 m, ~1024 x 1024 crops near
Marseille), matching img_01-img_02-img_03 from automatic seeds yields at least 50 000 three-ray
points (group 3) whose forward-backward matching differences are below 0.2 px RMS.

Combination order (reference, forward, backward) = (img_02, img_01, img_03), from the RPCs'
viewing geometry (test_reference_is_the_most_nadir): the ground point of the image centre moves
by 0.12 m (img_01), 0.07 m (img_02) and 0.14 m (img_03) per metre of height, so img_02 looks
closest to nadir; and it lies between the other two along track (500 m of height move an img_02
point by +113 rows in img_01 and by -111 rows in img_03: opposite parallax, B/H ~0.11 to each),
i.e. the triplet's middle image, like HRG between HRS1 and HRS2 in Kornus et al. 2006. img_01 is the
forward view (its ground shift per height points north-east, ahead of a descending orbit),
img_03 the backward one (south).

Parameters: the LsmParams defaults (template 19, rho > 0.6, ellipse < 0.1 px,
shift < 2.5 px, 10 iterations) with STEP = 3 px (nodes = ~1005^2 / 9 = 112 000 per combination;
STEP 4 gives 63 000 nodes and ~43 500 group 3 points, short of 50 000), automatic seeds in every
tile, and the RPCs' own height range (40 .. 1090 m ellipsoidal, which holds Marseille's relief).
Forward-backward differences are measured on the final observations of the group 3 points, for
each combination's image pair (consistency.observation_pairs + forward_backward)."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.consistency import fb_summary, forward_backward, observation_pairs
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.pair_geometry import ImagePair, predict
from pushbroom.algorithms.matching.params import GrowParams
from tests.helpers.pleiades_scene import in_order
from tests.helpers.real_dsm import TRIPLET_STEP

pytestmark = [pytest.mark.slow, pytest.mark.real]

PARAMS = GrowParams(step=TRIPLET_STEP)
# combinations as (template image, search image) indices in combination order, and the block
# image ids (1, 2, 3 = reference, forward, backward) of their observations
COMBINATIONS = {"a": (0, 1), "b": (0, 2), "c": (2, 1)}
MIN_GROUP3 = 50_000
MAX_FB_RMS = 0.2


def off_nadir(model):
    """Ground shift per metre of height (tangent of the off-nadir angle) at the image centre."""
    c, r = np.array([model.size[0] / 2.0]), np.array([model.size[1] / 2.0])
    lon0, lat0 = model.image_to_ground(c, r, np.array([0.0]))
    lon1, lat1 = model.image_to_ground(c, r, np.array([100.0]))
    east = (lon1 - lon0)[0] * 111_320.0 * np.cos(np.radians(lat0[0]))
    north = (lat1 - lat0)[0] * 110_574.0
    return float(np.hypot(east, north) / 100.0), float(np.degrees(np.arctan2(east, north)))


def test_reference_is_the_most_nadir(pleiades_triplet):
    models = [sensors.load(p) for p in pleiades_triplet]
    tangents = [off_nadir(m)[0] for m in models]
    assert int(np.argmin(tangents)) == 1, tangents  # img_02
    # img_02 lies between img_01 and img_03 along track: opposite row parallax
    ref = models[1]
    c, r = np.array([512.0]), np.array([512.0])
    shift = []
    for other in (models[0], models[2]):
        _, y_lo = predict(ref, other, c, r, np.array([0.0]))
        _, y_hi = predict(ref, other, c, r, np.array([500.0]))
        shift.append(float(y_hi[0] - y_lo[0]))
    assert shift[0] * shift[1] < 0 and min(abs(s) for s in shift) > 50, shift


@pytest.fixture(scope="module")
def matched(pleiades_triplet, region_growing_triplet_dsms):
    """The triplet's points (region growing at STEP = TRIPLET_STEP, conftest.py) and the forward-backward
    summary of each combination's group 3 points."""
    points, models = region_growing_triplet_dsms["points"], region_growing_triplet_dsms["models"]
    images = [Image(p) for p in in_order(pleiades_triplet)]
    group3 = points.points["group"] == 3
    fb = {
        label: fb_summary(
            forward_backward(
                ImagePair(images[i], images[j], models[i], models[j]),
                observation_pairs(points, i + 1, j + 1, which=group3),
                PARAMS,
            )
        )
        for label, (i, j) in COMBINATIONS.items()
    }
    return points, fb


@pytest.mark.ratchet
def test_group3_points_from_automatic_seeds(matched):
    points, _ = matched
    counts = points.group_counts()
    assert counts[3] >= MIN_GROUP3, (counts, points.stats)


@pytest.mark.parametrize("label", sorted(COMBINATIONS))
@pytest.mark.ratchet
def test_forward_backward_rms_of_group3(matched, label):
    points, fb = matched
    s = fb[label]
    assert s["points"] == points.group_counts()[3]
    assert s["rms"] < MAX_FB_RMS, s
    # nearly every point matches back (no censoring of the RMS), and blunders are rare
    assert s["failed"] < 0.05 * s["points"], s
    assert s["over"] < 0.005, s
