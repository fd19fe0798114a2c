"""The settings of the matching, intersection, DEM and orthorectification steps: defaults are valid,
values no step can use are InputErrors before any work starts."""
import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.steps.block_intersection import IntersectParams
from pushbroom.algorithms.steps.block_matching import MatchParams
from pushbroom.algorithms.steps.orthoimage import OrthoParams
from pushbroom.algorithms.surface.tin_dem import DemParams


@pytest.mark.parametrize("params", [MatchParams(), IntersectParams(), DemParams(), OrthoParams()])
def test_defaults_are_valid(params):
    assert params.check() is params


@pytest.mark.parametrize("params", [
    MatchParams(strategy="hierarchy"), MatchParams(seeds="none"), MatchParams(execution=Execution("threads", 0)),
    MatchParams(grow=GrowParams(template=8)),
    IntersectParams(kind="control_points"), IntersectParams(sigma=0.0),
    DemParams(cell=0.0), DemParams(datum="navd88"), DemParams(iterations=0),
    OrthoParams(resampling="nearest"), OrthoParams(dem_heights="egm2008"), OrthoParams(max_error=0.0),
])
def test_unusable_settings_are_input_errors(params):
    with pytest.raises(InputError):
        params.check()


def test_coarse_to_fine_settings_are_checked_only_for_that_strategy():
    bad = CoarseToFineParams(tile=10)
    assert MatchParams(coarse_to_fine=bad).check()      # region growing does not use them
    with pytest.raises(InputError):
        bad.check()
