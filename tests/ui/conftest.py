"""Fixtures of the measurement window tests: the small SPOT 5 triplet with markers painted at its
points (signalised control points; the unmarked scene's points lie in uniform fields where matching
has nothing to hold on to, see tests/algorithms/test_measurement_transfer.py) and a template block."""
import pytest


@pytest.fixture(scope="session")
def marked_scene(simulated):
    """simulate_scene paths of SceneConfig.small(markers=True), shared read-only."""
    from pushbroom.algorithms.simulation import SceneConfig
    return simulated(SceneConfig.small(markers=True))


@pytest.fixture(scope="session")
def marked_block(marked_scene, tmp_path_factory):
    """A template block (copy it before changing it) of the marked scene's HRG, HRS1, HRS2 at the
    mean height of its points."""
    import csv

    import numpy as np

    from pushbroom.algorithms.block import Block
    with open(marked_scene["points"], newline="") as f:
        height = float(np.mean([float(r["h"]) for r in csv.DictReader(f)]))
    path = tmp_path_factory.mktemp("marked_block") / "template.gpkg"
    images = Block.open_images([marked_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    Block.create(path, images, height=height)
    return path
