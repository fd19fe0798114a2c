"""The search window both matchers read (pair_geometry.search_box) against a dense brute-force
projection of the image-1 box over the height range, on the real Pleiades triplet's RPCs."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.pair_geometry import predict, search_box


@pytest.fixture(scope="module")
def pair(pleiades_triplet):
    return sensors.load(pleiades_triplet[1]), sensors.load(pleiades_triplet[0])


def brute_force(model1, model2, box, hr):
    """The bounding box of 101 x 101 image-1 points of `box` at 41 heights projected into image 2."""
    gx, gy = np.meshgrid(np.linspace(box[0], box[2], 101), np.linspace(box[1], box[3], 101))
    xs, ys = zip(*(predict(model1, model2, gx, gy, np.full(gx.shape, h)) for h in np.linspace(*hr, 41)))
    return np.min(xs), np.min(ys), np.max(xs), np.max(ys)


@pytest.mark.parametrize("box", [(0, 0, 1024, 1024), (300, 500, 812, 700), (900, 10, 1000, 1000)])
def test_the_search_box_holds_every_projection_of_the_box(pair, box):
    hr = pair[0].height_range
    dense = np.array(brute_force(*pair, box, hr))
    predicted = np.array(search_box(*pair, box, hr, 0.0))
    # the extremes of the dense projection lie on the grid's samples (box corners, end heights)
    assert np.abs(predicted - dense).max() < 1e-6
    wide = np.array(search_box(*pair, box, hr, 1.0))  # a margin holds every projection
    assert (wide[:2] <= dense[:2]).all() and (wide[2:] >= dense[2:]).all()


def test_the_margin_widens_the_box_on_every_side(pair):
    hr = pair[0].height_range
    tight = np.array(search_box(*pair, (0, 0, 100, 100), hr, 0.0))
    assert np.allclose(np.array(search_box(*pair, (0, 0, 100, 100), hr, 7.5)) - tight, [-7.5, -7.5, 7.5, 7.5])


class Elsewhere:
    """A model whose every ground point lies outside its image (NaN), like a pair that does not overlap."""

    def ground_to_image(self, lon, lat, h):
        return np.full(np.shape(lon), np.nan), np.full(np.shape(lon), np.nan)


def test_no_finite_prediction_is_no_search_box(pair):
    assert search_box(pair[0], Elsewhere(), (0, 0, 100, 100), pair[0].height_range, 10.0) is None
