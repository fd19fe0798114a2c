"""The stored points of the three matching strategies, byte for byte, against a record made before the
matching room was rebuilt (issue 38): region growing, dense (with MPGC) and coarse-to-fine, on the small
simulated triplet and its pair, each over several tiles. A refactoring of the matching must leave these bytes
as they were; a change of the science must rewrite the record on purpose, saying why in its commit:
`PUSHBROOM_RECORD_GOLDEN=1 pytest tests/algorithms/steps/test_matching_golden.py`.

The record holds the SHA-256 of each stored points and observations array and their counts (to say how far a
failing case is off)."""

import hashlib
import json
import os
import shutil

import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowingSettings
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points

RECORD = os.path.join(os.path.dirname(__file__), "..", "..", "golden", "matching.json")
NAMES = {"triplet": ("HRG", "HRS1", "HRS2"), "pair": ("HRG", "HRS1")}
#: each strategy's settings: small tiles, so that every case runs several of them
CASES = {
    "region_growing": dict(
        strategy="region_growing", settings=RegionGrowingSettings(grow=GrowParams(step=6, tile=256))
    ),
    "dense": dict(strategy="dense", settings=DenseParams(step=3, tile=256, mpgc=True)),
    "coarse_to_fine": dict(strategy="coarse_to_fine", settings=CoarseToFineParams(tile=512, grid=8)),
}


@pytest.fixture(scope="module")
def blocks(simulated, tmp_path_factory):
    """{'triplet' | 'pair': a template block of the error-free small scene} and its DSM's height range +- 30 m."""
    paths = simulated(SceneConfig.small(error_scale=0.0))
    lo, hi = read_dem(paths["dsm"]).height_range
    folder = tmp_path_factory.mktemp("golden")
    made = {}
    for kind, names in NAMES.items():
        made[kind] = str(folder / f"{kind}.gpkg")
        Block.create(
            made[kind], Block.open_images([paths["images"][n]["imagery"] for n in names]), height=(lo + hi) / 2
        )
    return made, (lo - 30.0, hi + 30.0)


def digest(block):
    """{'points' | 'observations': (SHA-256 of the stored array's bytes, its length)} of the block's mass points."""
    mass = Block(block).points()
    return {
        k: [hashlib.sha256(a.tobytes()).hexdigest(), len(a)]
        for k, a in (("points", mass.points), ("observations", mass.observations))
    }


@pytest.mark.slow
@pytest.mark.parametrize("kind", NAMES)
@pytest.mark.parametrize("strategy", CASES)
def test_stored_points_are_as_recorded(blocks, strategy, kind, tmp_path):
    templates, (lo, hi) = blocks
    path = str(tmp_path / "block.gpkg")
    shutil.copy(templates[kind], path)
    match_block_points(path, MatchParams(min_height=lo, max_height=hi, **CASES[strategy]))
    found, case = digest(path), f"{strategy} {kind}"
    with open(RECORD) as f:
        record = json.load(f)
    if os.environ.get("PUSHBROOM_RECORD_GOLDEN"):
        record[case] = found
        with open(RECORD, "w") as f:
            json.dump(record, f, indent=1, sort_keys=True)
            f.write("\n")
    assert found == record[case], f"{case}: stored {found}, recorded {record[case]}"
