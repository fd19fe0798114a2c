"""The heights of terrain on Earth every height a user gives is checked against (height_range.py)."""

import math

import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.height_range import PLAUSIBLE_HEIGHTS, check_height, height_range


def test_the_plausible_heights_hold_the_lowest_and_highest_terrain_either_way():
    # orthometric: the Dead Sea shore -430 m, Everest 8849 m; ellipsoidal: the geoid lies -106 .. +85 m from the
    # ellipsoid (sea level at its lowest, in the Indian Ocean, is at -106 m; any terrain moves by at most 106 m)
    low, high = PLAUSIBLE_HEIGHTS
    assert low < -430.0 - 50.0 and low < -106.0
    assert high > 8849.0 + 85.0


@pytest.mark.parametrize("value", [60000.0, -20000.0, 9001.0, math.nan])
def test_a_height_off_the_earth_is_refused_with_the_range(value):
    with pytest.raises(
        InputError,
        match=r"the mean height .*(outside the heights of terrain on Earth|a number of "
        r"metres within) .*-500 \.\. 9000 m",
    ):
        check_height(value, "the mean height")


def test_matching_heights_are_checked_where_given():
    assert height_range(100.0, 900.0, (0.0, 50.0)) == (100.0, 900.0)
    assert height_range(None, None, (0.0, 50.0)) == (0.0, 50.0)  # the block's range, as recorded
    with pytest.raises(InputError, match=r"the highest terrain height \(MAX_HEIGHT\) of 6e\+06 m"):
        height_range(100.0, 6e6, None)


def test_matchpoints_refuses_a_range_off_the_earth_before_matching(small_scene_block):
    # issue 36: the range is checked where matching reads it, before any image is read; the block is unchanged
    from pushbroom.algorithms.block import Block
    from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points

    before = Block(small_scene_block[0]).info()
    with pytest.raises(InputError, match=r"the lowest terrain height \(MIN_HEIGHT\) of 20000 m lies outside"):
        match_block_points(small_scene_block[0], MatchParams(min_height=20000.0, max_height=30000.0))
    assert Block(small_scene_block[0]).info() == before
