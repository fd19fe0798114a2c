"""The settings rules of the step entry points (adjust_block, fit_block_rpcs, assess_accuracy): text
parameters parsed, contradictory settings refused with InputError before any work."""

import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.quality.assess_accuracy import AssessParams
from pushbroom.algorithms.steps.adjust_block import LAGRANGE_AUTO, AdjustParams, parse_counts, parse_priors
from pushbroom.algorithms.steps.block_rpcs import RpcParams, cube_heights, cube_warning, selected_images


def test_priors_parse_commas_and_semicolons():
    # pattern=sigma items, separated by commas or semicolons; empty text: no priors
    assert parse_priors("bias:shift=10; pitch_0 = 1e-5,") == {"bias:shift": 10.0, "pitch_0": 1e-5}
    assert parse_priors("") == {} and parse_priors(None) == {}


@pytest.mark.parametrize("text", ["bias:shift", "bias:shift=ten", "=x"])
def test_a_prior_without_a_number_is_refused(text):
    with pytest.raises(InputError, match="pattern=sigma"):
        parse_priors(text)


def test_control_series_counts():
    assert parse_counts("4, 6;10") == [4, 6, 10]
    assert parse_counts("") == [] and parse_counts(None) == []
    with pytest.raises(InputError, match="whole numbers"):
        parse_counts("4,six")


def test_adjust_params_free_and_auto():
    # "auto" in any case is the automatic selection; named parameters are a list
    assert AdjustParams(free=" Auto ").auto
    params = AdjustParams(free="bias:shift, look:1")
    assert not params.auto and params.free_list == ["bias:shift", " look:1"]
    assert LAGRANGE_AUTO == ["lagrange:attitude", "lagrange:offset"]


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"model": "spline"}, "orientation model"),
        ({"reference_heights": "geoid"}, "reference DTM heights"),
        ({"residual_vectors": "memory:vectors"}, "not to a temporary memory layer"),
        ({"priors": "bias"}, "pattern=sigma"),
        ({"control_series": "a,b"}, "whole numbers"),
    ],
)
def test_adjust_params_check_refuses(settings, message):
    with pytest.raises(InputError, match=message):
        AdjustParams(**settings).check()


def test_rpc_cube_heights_both_or_neither():
    assert cube_heights(Block("unused.gpkg"), 100.0, 900.0) == (100.0, 900.0)  # given: the block is not read
    with pytest.raises(InputError, match="both the lowest and the highest"):
        cube_heights(Block("unused.gpkg"), 100.0, None)
    # issue 36: a cube at 20-30 km was fitted and written without a word
    with pytest.raises(
        InputError,
        match=r"the highest height of the RPC cube \(MAX_HEIGHT\) of 30000 m lies outside "
        r"the heights of terrain on Earth \(-500 \.\. 9000 m",
    ):
        cube_heights(Block("unused.gpkg"), 100.0, 30000.0)
    # swapped: refused before the fit, not warned about as a cube that leaves out terrain
    with pytest.raises(InputError, match=r"the lowest height of the RPC cube \(900 m\) is above the highest \(100 m\)"):
        cube_heights(Block("unused.gpkg"), 900.0, 100.0)
    # a cube that leaves out part of the terrain (280 .. 970 m) is fitted, with a warning
    assert cube_warning((0.0, 500.0), (280.0, 970.0)).startswith(
        "the RPC cube's heights 0 .. 500 m leave out some of the block's terrain (280 .. 970 m)"
    )
    assert cube_warning((200.0, 1100.0), (280.0, 970.0)) is None and cube_warning((0.0, 1.0), None) is None
    with pytest.raises(InputError, match="at least 4"):
        RpcParams(grid=3).check()


def test_rpc_selected_images():
    rows = [{"name": "HRG", "id": 1}, {"name": "HRS1", "id": 2}]
    assert selected_images(rows, " ") == rows
    assert selected_images(rows, "HRS1") == [rows[1]]
    with pytest.raises(InputError, match="HRS2 is not in the block; it has HRG, HRS1"):
        selected_images(rows, "HRS2")


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"dh": "dh.tif"}, "the dh raster needs a DEM input"),
        ({"class_raster": "classes.tif", "class_polygons": object()}, "not both"),
        ({"points_heights": "geoid"}, "heights must be one of"),
    ],
)
def test_assess_params_check_refuses(settings, message):
    with pytest.raises(InputError, match=message):
        AssessParams(reference="ref.tif", report="r.html", **settings).check()
