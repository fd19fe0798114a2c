"""The matching-strategy interface (matching/strategy.py): a fourth strategy is one module (the toy of
tests/helpers/toy_strategy.py) and its registration, and the matching step runs it, tile by tile, as it runs the
built-in ones, without knowing its name."""

import ast
import pathlib
import shutil

import numpy as np
import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.pair_geometry import predict
from pushbroom.algorithms.matching.strategy import register, strategy_named
from pushbroom.algorithms.matching_strategies import registered
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points
from tests.helpers.toy_strategy import ToyGrid, ToySettings

STEP_MODULE = pathlib.Path(__file__).resolve().parents[3] / "algorithms" / "steps" / "block_matching.py"


@pytest.fixture(scope="module")
def triplet_block(simulated, tmp_path_factory):
    paths = simulated(SceneConfig.small(error_scale=0.0))
    lo, hi = read_dem(paths["dsm"]).height_range
    path = tmp_path_factory.mktemp("toy") / "template.gpkg"
    Block.create(
        path, Block.open_images([paths["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")]), height=(lo + hi) / 2
    )
    return str(path), (lo, hi)


def test_the_step_runs_a_strategy_it_does_not_know(triplet_block, tmp_path):
    template, (lo, hi) = triplet_block
    path = str(tmp_path / "block.gpkg")
    shutil.copy(template, path)
    settings = ToySettings(step=25, tile=128)
    result = match_block_points(path, MatchParams(min_height=lo, max_height=hi, strategy="toy_grid", settings=settings))
    blk = Block(path)
    mass = blk.points()
    ids = {r["name"]: r["id"] for r in blk.images()}
    models = blk.models([ids["HRG"], ids["HRS1"], ids["HRS2"]])
    cols, rows = models[ids["HRG"]].size
    # the grid counted per tile of 128 px, independently of the toy's own arithmetic
    per_tile = [
        len(range(x0, min(x0 + 128, cols), 25)) * len(range(y0, min(y0 + 128, rows), 25))
        for y0 in range(0, rows, 128)
        for x0 in range(0, cols, 128)
    ]
    assert len(mass) == result.count == sum(per_tile) > 100
    np.testing.assert_array_equal(mass.points["id"], np.arange(1, len(mass) + 1))  # numbered over the tiles
    x, y = mass.coordinates(ids["HRG"])
    for name in ("HRS1", "HRS2"):
        col, row = mass.coordinates(ids[name])
        want = predict(models[ids["HRG"]], models[ids[name]], x, y, (lo + hi) / 2)
        np.testing.assert_allclose(np.column_stack([col, row]), np.column_stack(want), atol=1e-9)
    assert blk.point_stats()["strategy"] == "toy_grid" and blk.point_stats()["spacing_px"] == 25.0


def test_the_registry_holds_the_built_in_strategies_and_refuses_a_taken_name():
    assert {"region_growing", "coarse_to_fine", "dense", "toy_grid"} <= set(registered())
    assert strategy_named("toy_grid") is ToyGrid

    class Impostor(ToyGrid):
        pass

    with pytest.raises(ValueError, match="'toy_grid' is taken by ToyGrid"):
        register(Impostor)
    with pytest.raises(InputError, match="must be one of .*region_growing.*got 'hierarchy'"):
        strategy_named("hierarchy")
    with pytest.raises(InputError, match="the toy_grid strategy takes ToySettings, got GrowParams"):
        from pushbroom.algorithms.matching.params import GrowParams

        MatchParams(strategy="toy_grid", settings=GrowParams()).check()


def test_the_matching_step_has_no_branch_on_a_strategy_name():
    """A name may be the default of MatchParams.strategy; no test, no dict and no call branches on one."""
    names = set(registered())
    tree = ast.parse(STEP_MODULE.read_text(encoding="utf-8"))
    branching = (ast.If, ast.IfExp, ast.Compare, ast.Dict, ast.Match, ast.Subscript)
    found = [
        (node.lineno, c.value)
        for node in ast.walk(tree)
        if isinstance(node, branching)
        for c in ast.walk(node)
        if isinstance(c, ast.Constant) and c.value in names
    ]
    assert found == []
