"""Graphical models saved before the matching room was rebuilt (issue 38) still run: the pipeline models as they
were at c00380d (tests/data/models_c00380d). Every parameter id they set still exists (both), and the
region-growing one, whose MPGC_REFINE now sets RegionGrowingSettings.mpgc and its other matchpoints keys the
settings of the region-growing strategy, runs end to end through qgis_process on the small simulated triplet, its
DEM checked against the simulator's true DSM. (The dense one's DENSE_REFINE, now DenseParams.lsm, is run by the
current dense model in tests/plugin/test_pipeline_model.py, which sets the same keys.)"""

import csv
import json
import pathlib

import numpy as np
import pytest
from qgis.core import QgsApplication, QgsProcessingModelAlgorithm

from tests.plugin.test_pipeline_model import OUTPUTS, band, warped

OLD = pathlib.Path(__file__).resolve().parents[1] / "data" / "models_c00380d"
MODELS = {"pushbroom_pipeline": ["HEIGHT=300"], "pushbroom_pipeline_dense": []}


@pytest.mark.parametrize("name", MODELS)
def test_every_parameter_an_old_model_sets_still_exists(pushbroom_provider, name):
    model = QgsProcessingModelAlgorithm()
    assert model.fromFile(str(OLD / f"{name}.model3"))
    registry = QgsApplication.processingRegistry()
    unknown = []
    for child in model.childAlgorithms().values():
        algorithm = registry.algorithmById(child.algorithmId())
        assert algorithm is not None, child.algorithmId()
        unknown += [
            f"{child.algorithmId()} {key}" for key in child.parameterSources() if not algorithm.parameterDefinition(key)
        ]
    assert unknown == []


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pushbroom_pipeline"])
def test_an_old_model_runs_end_to_end(name, small_scene, qgis_process, tmp_path):
    with open(small_scene["points"], newline="") as f:
        ids = [r["id"] for r in csv.DictReader(f)]
    result = qgis_process(
        "run",
        str(OLD / f"{name}.model3"),
        "--",
        *(f"IMAGES={small_scene['images'][n]['imagery']}" for n in ("HRG", "HRS1", "HRS2")),
        *MODELS[name],
        f"POINTS={small_scene['points']}",
        f"CHECK_IDS={','.join(ids[5:])}",
        "MEAS_SUFFIX=_meas",
        f"REFERENCE={small_scene['dsm']}",
        f"CLASS_RASTER={small_scene['classes']}",
        "THREADS=2",
        *(f"{k}={tmp_path / v}" for k, v in OUTPUTS.items()),
    )
    assert all((tmp_path / v).exists() for v in OUTPUTS.values()), json.dumps(result["log"])[-2000:]
    dh = band(tmp_path / "dem.tif") - warped(small_scene["dsm"], tmp_path / "dem.tif")
    assert np.isfinite(dh).mean() > 0.3 and np.median(np.abs(dh[np.isfinite(dh)])) < 4.0
