"""The steps that store points keep the block's good results where they find nothing, or far fewer
(block/replacement.py): matchpoints with a height range beside the terrain, selecttiepoints with nothing or no
point of the group asked for. The exact cases of issue 36, on the small simulated triplet."""

import os
import shutil

import numpy as np
import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.steps.block_creation import CreateParams, create_block
from pushbroom.algorithms.steps.block_matching import (
    MatchParams,
    check_height_range,
    match_block_points,
    terrain_source,
)
from pushbroom.algorithms.steps.block_tie_points import TieParams, select_block_tie_points
from tests.helpers.feedback import Feedback
from tests.helpers.fingerprint import fingerprint
from tests.helpers.points_synthetic import two_ray_points

#: the issue's height range, 5 km above the simulated terrain
BESIDE = {"min_height": 6000.0, "max_height": 6500.0}


def files(block):
    """What the folder of `block` holds, byte for byte (its point folders too)."""
    return fingerprint(os.path.dirname(block))


@pytest.fixture
def matched(small_scene_block, tmp_path):
    """A copy of the small triplet's block (terrain range: its mean height +- 500 m, a guess) holding 500
    stored two-ray mass points and 20 tie points."""
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    Block(path).store_points(two_ray_points(500, np.random.default_rng(0)))
    Block(path).store_points(two_ray_points(20, np.random.default_rng(1)), "tie_points")
    return path


def test_a_range_beside_the_dem_terrain_is_refused_before_matching(small_scene, tmp_path):
    path = str(tmp_path / "dem.gpkg")
    create_block(
        path, [small_scene["images"][n]["imagery"] for n in ("HRG", "HRS1")], CreateParams(dem=small_scene["dsm"])
    )
    lo, hi = Block(path).height_range()
    dem_lo, dem_hi = read_dem(small_scene["dsm"]).height_range
    assert dem_lo <= lo < hi <= dem_hi  # the DEM's heights under the footprints
    before = files(path)
    for strategy in ("region_growing", "dense"):
        with pytest.raises(
            InputError,
            match=rf"6000 to 6500 m .* miss the block's terrain heights, "
            rf"{lo:.0f} to {hi:.0f} m \(from its DEM\)",
        ):
            match_block_points(path, MatchParams(strategy=strategy, **BESIDE))
    assert files(path) == before and "mass_points" not in Block(path).info()


@pytest.mark.parametrize(
    "searched, warned",
    [
        ((6000.0, 6500.0), "miss the block's terrain heights, 280 to 970 m"),  # beside a guessed range: a warning
        ((800.0, 1500.0), "cover only 25% of"),  # (970 - 800) / (970 - 280)
        ((200.0, 700.0), None),  # 61 %: no word
    ],
)
def test_a_range_missing_a_guessed_terrain_or_most_of_it_is_a_warning(searched, warned):
    log = Feedback()
    check_height_range(searched, (280.0, 970.0), ("the mean height it was created at", False), log)
    if warned:
        assert any(warned in m for m in log.messages), log.messages
    else:
        assert log.messages == []


def test_a_range_beside_the_terrain_of_the_height_search_is_refused():
    """The issue's block took its terrain heights from createblock's height search: measured, so a range
    beside them is an error, as beside a DEM's."""
    source = terrain_source({"height_search": "318 points matched over 0 to 2000 m"})
    assert source == ("matching at its creation", True)
    with pytest.raises(
        InputError,
        match=r"6000 to 6500 m .* miss the block's terrain heights, 280 to 970 m "
        r"\(from matching at its creation\)",
    ):
        check_height_range((6000.0, 6500.0), (280.0, 970.0), source)


def test_region_growing_that_finds_nothing_keeps_the_stored_points(matched):
    before, info = files(matched), Block(matched).info()
    log = Feedback()
    with pytest.raises(InputError, match="0 mass points against 500.*keeps its 500 mass points.*REPLACE_FEWER"):
        match_block_points(matched, MatchParams(**BESIDE), feedback=log)
    assert any("miss the block's terrain heights" in m for m in log.messages)  # said before matching
    assert any("found no matched point" in m for m in log.messages)
    assert files(matched) == before and Block(matched).info() == info  # byte for byte; no new folder
    match_block_points(matched, MatchParams(replace_fewer=True, **BESIDE))
    assert Block(matched).info()["mass_points_count"] == "0" and len(Block(matched).points()) == 0


def test_tie_points_from_nothing_or_from_no_point_of_the_group_are_refused(matched):
    before = files(matched)
    with pytest.raises(
        InputError,
        match=r"no point of group 3 or higher \(group 1: 500, group 2: 0, group 3: 0; "
        r".*Set MIN_GROUP to 1 or lower, or match three images",
    ):
        select_block_tie_points(matched, TieParams(min_group=3))
    Block(matched).store_points(two_ray_points(0), replace_fewer=True)  # a matching that found nothing
    after_empty = files(matched)
    with pytest.raises(InputError, match=r"mass points are empty \(pushbroom:matchpoints found none\)"):
        select_block_tie_points(matched, TieParams())
    assert files(matched) == after_empty
    assert {k: v for k, v in before.items() if "tie_points" in k} == {
        k: v for k, v in after_empty.items() if "tie_points" in k
    }
    assert Block(matched).info()["tie_points_count"] == "20"
