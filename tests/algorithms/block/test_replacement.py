"""A step that finds nothing, or far fewer than before, never replaces good results silently
(algorithms/block/replacement.py): the store of points and of control points refuses far fewer than the block
holds, leaves the block and its point folder as they were, and replaces them only when asked."""

import os

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.block.points import write_part
from pushbroom.algorithms.block.replacement import Tally, check_replacement
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.points import MultiPoints
from tests.helpers.feedback import Feedback
from tests.helpers.fingerprint import fingerprint
from tests.helpers.points_synthetic import FlatModel, synthetic

DISPLAY = (FlatModel(), 1, 0.0)


@pytest.fixture
def block(tmp_path):
    path = tmp_path / "b.gpkg"
    create_schema(path)
    return str(path)


def snapshot(block):
    """What a refused store must leave as it was: block_info, the layer's rows, everything beside the block."""
    beside = {
        path: digest for path, digest in fingerprint(os.path.dirname(block)).items() if path != os.path.basename(block)
    }
    return Block(block).info(), len(Block(block).points()), beside


def with_spacing(points, spacing):
    """`points` whose stats record the matching's spacing (px), as matchpoints stores them."""
    return MultiPoints(points.points, points.observations, {**points.stats, "spacing_px": spacing})


@pytest.mark.parametrize(
    "tally, refused",
    [
        (Tally("points", 2828, 0), True),  # the matching found nothing
        (Tally("points", 2828, 1413), True),  # just below half
        (Tally("points", 2828, 1414), False),  # half: a rerun with other thresholds
        (Tally("points", 0, 0), False),  # nothing stored: nothing to keep
        (Tally("points", 2828, 400, expected=707.0), False),  # STEP 20 after STEP 10 expects a quarter
        (Tally("points", 2828, 300, expected=707.0), True),  # and refuses below half of that
        (Tally("points", 2828, 1000, expected=11312.0), True),  # a finer run is held to half the stored count
    ],
)
def test_far_fewer_is_below_half_of_what_the_stored_result_gives_at_the_new_spacing(tally, refused):
    assert tally.far_fewer == refused


def test_a_store_of_no_points_keeps_the_block_as_it_was(block, tmp_path):
    Block(block).store_points(with_spacing(synthetic(3000), 10), display=DISPLAY)
    before = snapshot(block)

    def nothing(folder):  # a fill that finds no point (a matching beside the terrain)
        return [write_part(folder, 0, MultiPoints())], {"spacing_px": 10}

    with pytest.raises(
        InputError,
        match=r"0 mass points against 3000.*keeps its 3000 mass points.*"
        r"pushbroom:matchpoints again with REPLACE_FEWER",
    ):
        Block(block).store_point_parts("mass_points", nothing, display=DISPLAY)
    assert snapshot(block) == before  # the same counts, layer rows and point folder, byte for byte; no new folder
    log = Feedback()
    Block(block).store_point_parts("mass_points", nothing, display=DISPLAY, feedback=log, replace_fewer=True)
    assert Block(block).info()["mass_points_count"] == "0" and len(Block(block).points()) == 0
    assert any("far fewer" in m and "REPLACE_FEWER" in m for m in log.messages)
    assert len(list(tmp_path.glob("b.mass_points.*"))) == 1  # the old folder removed after the switch


def test_far_fewer_points_are_judged_at_the_new_spacing(block):
    Block(block).store_points(with_spacing(synthetic(3000), 10))
    # STEP 20 expects about 750 points: 300 is a failed run, 500 a coarser one
    with pytest.raises(InputError, match=r"300 mass points against 3000, about 750 at the new, coarser spacing"):
        Block(block).store_points(with_spacing(synthetic(300), 20))
    Block(block).store_points(with_spacing(synthetic(500), 20))
    assert Block(block).info()["mass_points_count"] == "500"
    # tie points: their CELL; a point folder of earlier versions without a spacing is compared by its count
    Block(block).store_points(synthetic(400), "tie_points")
    with pytest.raises(InputError, match="pushbroom:selecttiepoints again"):
        Block(block).store_points(
            MultiPoints(synthetic(100).points, synthetic(100).observations, {"tie_cell": 100}), "tie_points"
        )


def test_a_damaged_stored_point_folder_is_replaced_without_asking(block, tmp_path):
    Block(block).store_points(synthetic(3000))
    stored = tmp_path / Block(block).info()["mass_points"]
    (stored / "index.json").write_text("{cut short")
    Block(block).store_points(synthetic(10))  # "run the step again" must work on a damaged file
    assert len(Block(block).points()) == 10


def control_points(n, measured):
    """n control points, the first `measured` of them measured in images 1 and 2."""
    points = np.zeros(n, POINT_DTYPE)
    points["name"] = [f"P{k}" for k in range(n)]
    points["role"], points["lon"], points["lat"], points["h"] = "control", -84.2, 36.6, 500.0
    points["sigma_e"] = points["sigma_n"] = points["sigma_h"] = 2.5
    meas = np.zeros(2 * measured, MEAS_DTYPE)
    meas["point"], meas["image_id"] = np.repeat(np.arange(measured), 2), np.tile([1, 2], measured)
    meas["col"], meas["row"], meas["sigma"] = 100.0, 200.0, 0.5
    return Observations(points, meas)


def test_an_import_without_measurements_keeps_the_measured_points(block):
    names = {"HRG": 1, "HRS1": 2}
    Block(block).save_control_points(control_points(7, 7), names=names)
    before = Block(block).control_points()
    # one unmeasured point for the block's 7 measured ones; the same 7 points unmeasured
    for new in (control_points(1, 0), control_points(7, 0)):
        with pytest.raises(InputError, match=r"0 image measurements against 14.*MODE merge.*REPLACE_FEWER"):
            Block(block).save_control_points(new, names=names)
        after = Block(block).control_points()
        assert after.points.tobytes() == before.points.tobytes()
        assert after.measurements.tobytes() == before.measurements.tobytes()
    merged = Block(block).save_control_points(control_points(1, 0), mode="merge", names=names)
    assert len(merged.points) == 7 and len(merged.measurements) == 14  # a merge never loses
    stored = Block(block).save_control_points(control_points(1, 0), names=names, replace_fewer=True)
    assert len(stored.points) == 1 and Block(block).info()["image_measurements"] == "0"


def test_check_replacement_warns_when_asked():
    log = Feedback()
    check_replacement([Tally("tie points", 36, 0)], True, "tie points", "pushbroom:selecttiepoints", feedback=log)
    assert log.messages == [
        "the new tie points are far fewer than the block's (0 tie points against 36): they "
        "replace them, as REPLACE_FEWER asks"
    ]
