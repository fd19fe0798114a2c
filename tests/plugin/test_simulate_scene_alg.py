"""pushbroom:simulatescene through Processing, chained into pushbroom:createblock."""

import csv
import os

import numpy as np
import pytest
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProcessingFeedback, QgsVectorLayer

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block


@pytest.mark.slow
def test_simulated_triplet_becomes_a_block(pushbroom_provider, tmp_path, log):
    scene = processing.run(
        "pushbroom:simulatescene",
        {
            "CONFIGURATION": 0,
            "SIZE_KM": 3.0,
            "SEED": 7,
            "POINTS": 60,
            "BLUNDERS": 1000,
            "OUTPUT": str(tmp_path / "scene"),
        },
        feedback=log,
    )
    assert len(scene["IMAGES"]) == 3
    for key in ("DSM", "DTM", "CLASSES", "ORTHOIMAGE", "POINTS", "TRUTH"):
        assert os.path.isfile(scene[key]), key
    # issue 36: a 3 km scene holds fewer than 60 open sites apart, and 1000 blunders need more measurements than
    # its points have; the warning says so, with the numbers the points file holds
    with open(scene["POINTS"], newline="") as f:
        points = list(csv.DictReader(f))
    blunders = sum(int(p[f"{name}_blunder"]) for p in points for name in ("HRG", "HRS1", "HRS2"))
    [warning] = [w for w in log.warnings if "control/check point candidates made" in w]
    assert warning.startswith(f"{len(points)} control/check point candidates made of the 60 asked: the scene holds ")
    assert (
        f"; {blunders} blunders made of the 1000 asked: the {len(points)} candidates have {3 * len(points)} "
        "image measurements"
        in warning
        and blunders == 3 * len(points)
    )
    context = QgsProcessingContext()
    result = processing.run(
        "pushbroom:createblock",
        {"IMAGES": scene["IMAGES"], "DEM": scene["DSM"], "OUTPUT": str(tmp_path / "block.gpkg")},
        context=context,
        feedback=QgsProcessingFeedback(),
    )
    rows = Block(result["OUTPUT"]).images()
    assert sorted(r["name"] for r in rows) == ["HRG", "HRS1", "HRS2"]
    # the stored model is the supplied one of each product
    for row in rows:
        stored = Block(result["OUTPUT"]).model(row["id"])
        supplied = sensors.load(row["image_path"])
        c, r = np.array([10.0, row["cols"] - 10.0]), np.array([10.0, row["rows"] - 10.0])
        assert np.array_equal(stored.image_to_ground(c, r, 300.0), supplied.image_to_ground(c, r, 300.0))
    # the footprints layer is queued for loading with its style
    details = context.layersToLoadOnCompletion()
    assert len(details) == 1
    source, detail = next(iter(details.items()))
    layer = QgsVectorLayer(source, "fp", "ogr")
    assert layer.isValid() and layer.featureCount() == 3
    detail.postProcessor().postProcessLayer(layer, context, QgsProcessingFeedback())
    assert layer.labelsEnabled()


def test_bad_scene_input_gives_the_engines_message(pushbroom_provider, tmp_path):
    """An orthoimage without georeferencing is refused with the engine's message; nothing is written."""
    from osgeo import gdal

    plain = tmp_path / "plain.tif"
    gdal.GetDriverByName("GTiff").Create(str(plain), 10, 10, 1)
    with pytest.raises(QgsProcessingException, match="cannot read the orthoimage"):
        processing.run(
            "pushbroom:simulatescene", {"SIZE_KM": 3.0, "ORTHOIMAGE": str(plain), "OUTPUT": str(tmp_path / "s")}
        )
    assert not (tmp_path / "s").exists()
