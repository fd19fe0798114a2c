"""The settings of the matching, intersection, DEM and orthorectification steps: defaults are valid,
values no step can use are InputErrors before any work starts."""

import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.height_range import height_range
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowingSettings
from pushbroom.algorithms.steps.block_intersection import IntersectParams
from pushbroom.algorithms.steps.block_matching import MatchParams
from pushbroom.algorithms.steps.orthoimage import OrthoParams
from pushbroom.algorithms.surface.tin_dem import DemParams


@pytest.mark.parametrize("params", [MatchParams(), IntersectParams(), DemParams(), OrthoParams()])
def test_defaults_are_valid(params):
    assert params.check() is params


@pytest.mark.parametrize(
    "params",
    [
        MatchParams(strategy="hierarchy"),
        MatchParams(settings=RegionGrowingSettings(seeds="none")),
        MatchParams(execution=Execution("threads", 0)),
        MatchParams(settings=RegionGrowingSettings(grow=GrowParams(template=8))),
        MatchParams(strategy="dense", settings=RegionGrowingSettings()),  # another strategy's settings
        IntersectParams(kind="control_points"),
        IntersectParams(sigma=0.0),
        DemParams(cell=0.0),
        DemParams(datum="navd88"),
        DemParams(iterations=0),
        OrthoParams(resampling="nearest"),
        OrthoParams(dem_heights="egm2008"),
        OrthoParams(max_error=0.0),
    ],
)
def test_unusable_settings_are_input_errors(params):
    with pytest.raises(InputError):
        params.check()


def test_the_strategy_checks_its_own_settings():
    with pytest.raises(InputError, match="tiles must be at least 512 px"):
        MatchParams(strategy="coarse_to_fine", settings=CoarseToFineParams(tile=10)).check()
    assert isinstance(MatchParams(strategy="coarse_to_fine").check().settings, CoarseToFineParams)  # the defaults


@pytest.mark.parametrize(
    "params, message",
    [
        (DemParams(cell=float("nan")), "the cell size must be a positive number, got nan"),
        (
            DemParams(fill=-1.0, radius=9),
            "the fill distance must be 0 or more cells, got -1.0; the radius must be 0 to",
        ),
    ],
)
def test_the_broken_setting_is_the_one_named(params, message):
    """Before: one sentence of every constraint of the DEM, whichever was broken."""
    with pytest.raises(InputError) as err:
        params.check()
    assert str(err.value).startswith(message)
    assert "datum" not in str(err.value) and "iterations" not in str(err.value)  # not the settings that hold


def test_a_height_range_upside_down_gives_both_heights():
    """Before: "height_range must be (h_min, h_max) with h_min <= h_max", from deep inside the matcher."""
    with pytest.raises(InputError, match=r"the lowest terrain height \(6500 m\) is above the highest \(6000 m\)"):
        height_range(6500.0, 6000.0, None)
    with pytest.raises(
        InputError,
        match=r"the highest terrain height \(MAX_HEIGHT\) must be a number of metres within "
        r"-500 .. 9000 m, not nan",
    ):
        height_range(100.0, float("nan"), None)
    assert height_range(6000.0, 6500.0, None) == (6000.0, 6500.0)
