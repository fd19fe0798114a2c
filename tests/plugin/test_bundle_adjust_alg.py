"""pushbroom:bundleadjust on a small simulated SPOT 5 triplet with injected look-angle errors:
the adjusted models land in the block and reproduce the true image positions of check points."""
import csv

import numpy as np
import pytest
from qgis import processing
from qgis.core import QgsProcessingException

from pushbroom.algorithms import block
from pushbroom.algorithms.adjustment.control_points import import_csv
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene


@pytest.fixture(scope="module")
def adjusted_block(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bundle")
    paths = simulate_scene(SceneConfig.small(points=30, error_scale=0.0), folder / "scene")
    images = block.open_images([paths["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    path = folder / "b.gpkg"
    block.create_block(path, images, height=300.0)
    ids = {r["name"]: r["id"] for r in block.read_images(path)}
    models = {i: block.load_model(path, i) for i in ids.values()}
    for i, model in models.items():                   # inject 20 urad look-angle errors
        model.orientation.corrections.look[:, 0] = (2e-5, -2e-5 if i % 2 else 2e-5)
    block.save_models(path, models)
    check = [r["id"] for r in csv.DictReader(open(paths["points"]))][19:]
    import_csv(path, paths["points"], suffix="_meas", check_ids=check)
    return str(path), paths, ids


def test_adjusts_and_stores_models(pushbroom_provider, adjusted_block, tmp_path):
    path, paths, ids = adjusted_block
    result = processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "look:0", "USE_TIE_POINTS": False,
                                                      "REPORT": str(tmp_path / "r.html")})
    assert 0.3 < result["SIGMA0"] < 3.0
    text = open(result["REPORT"]).read()
    assert "HRS2 psi_y_0" in text and "dH" in text
    rows = list(csv.DictReader(open(paths["points"])))
    for name, i in ids.items():
        model = block.load_model(path, i)
        assert model.orientation.corrections.look[0, 0] == pytest.approx(0.0, abs=3e-6)
        col, row = model.ground_to_image(*(np.array([float(r[k]) for r in rows]) for k in ("lon", "lat", "h")))
        true = np.array([[float(r[f"{name}_col"]), float(r[f"{name}_row"])] for r in rows])
        assert np.sqrt(np.mean((col - true[:, 0]) ** 2 + (row - true[:, 1]) ** 2)) < 0.3


def test_clear_errors(pushbroom_provider, adjusted_block):
    path = adjusted_block[0]
    with pytest.raises(QgsProcessingException, match="no orientation parameter matches"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "psi_q_0", "USE_TIE_POINTS": False})
    with pytest.raises(QgsProcessingException, match="tie points"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "look:0", "USE_TIE_POINTS": True})
