"""The project's own sensor-model file: exact round trip through sensors.save / sensors.load."""

import json

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.errors import MetadataError


def grid(model):
    cols, rows = model.size
    c, r = np.meshgrid(np.linspace(0, cols, 9), np.linspace(0, rows, 9))
    return c.ravel(), r.ravel()


def assert_same_model(a, b, h):
    c, r = grid(a)
    assert a.size == b.size
    lon, lat = a.image_to_ground(c, r, h)
    assert np.array_equal(np.array(b.image_to_ground(c, r, h)), np.array([lon, lat]))
    # ground_to_image iterates from a start fitted at construction: equal to its tolerance
    assert np.allclose(b.ground_to_image(lon, lat, h), a.ground_to_image(lon, lat, h), rtol=0, atol=1e-6)


def test_spot_model_with_corrections_round_trips_exactly(spot5_dim, tmp_path):
    model = sensors.load(spot5_dim)
    corr = model.orientation.corrections
    corr.position[:, 1] = [3.0, -2.0, 1.5]
    corr.attitude[1, 0] = 2e-5
    corr.look[1, :] = [1e-5, -3e-6, 2e-7, -1e-8]
    path = tmp_path / "hrg.pbmodel.json"
    sensors.save(model, path)
    again = sensors.load(path)
    assert again.drift == model.drift
    assert np.array_equal(again.orientation.corrections.look, corr.look)
    assert again.orientation.epoch == model.orientation.epoch
    assert_same_model(model, again, 250.0)
    # the corrections matter: the same model without them maps elsewhere
    plain = sensors.load(spot5_dim)
    assert (
        np.max(np.abs(np.subtract(plain.image_to_ground(10.0, 10.0, 0.0), again.image_to_ground(10.0, 10.0, 0.0))))
        > 1e-5
    )


def test_spot2_with_drift_off_round_trips(spot2_dim, tmp_path):
    from pushbroom.algorithms.sensors.spot import SpotModel

    model = SpotModel.from_dimap(spot2_dim, drift=False)
    sensors.save(model, tmp_path / "a.pbmodel.json")
    again = sensors.load(tmp_path / "a.pbmodel.json")
    assert again.drift is False
    assert_same_model(model, again, 0.0)


def test_rpc_model_with_crop_round_trips_exactly(ventoux_image, tmp_path):
    model = sensors.load(ventoux_image)
    assert model.offset != (0.0, 0.0)
    sensors.save(model, tmp_path / "r.pbmodel.json")
    again = sensors.load(tmp_path / "r.pbmodel.json")
    assert_same_model(model, again, 1000.0)


@pytest.mark.parametrize(
    "text, message",
    [
        ("{not json", "cannot read"),
        ('{"format": "something-else"}', "not a Pushbroom"),
        ('{"format": "pushbroom-sensor-model", "version": 99, "kind": "spot"}', "version"),
        ('{"format": "pushbroom-sensor-model", "version": 1, "kind": "lidar"}', "unknown model kind"),
        (
            '{"format": "pushbroom-sensor-model", "version": 1, "kind": "spot", "drift": true, "orientation": {}}',
            "damaged",
        ),
    ],
)
def test_damaged_model_files_raise_metadata_error(tmp_path, text, message):
    path = tmp_path / "x.pbmodel.json"
    path.write_text(text)
    with pytest.raises(MetadataError, match=message):
        sensors.load(path)


def test_truncated_model_file_raises_metadata_error(spot5_dim, tmp_path):
    path = tmp_path / "t.pbmodel.json"
    sensors.save(sensors.load(spot5_dim), path)
    doc = json.loads(path.read_text())
    del doc["orientation"]["eph_pos"]
    path.write_text(json.dumps(doc))
    with pytest.raises(MetadataError):
        sensors.load(path)


@pytest.mark.parametrize("size", [[1], [-5, 3], [0, 10], "ab", None, [1e400, 3]])
def test_rpc_model_file_with_a_bad_size_raises_metadata_error(tmp_path, size):
    from pushbroom.algorithms.sensors.rpc import RpcModel
    from tests.helpers.rpc_synthetic import synthetic_coefficients

    path = tmp_path / "r.pbmodel.json"
    sensors.save(RpcModel(synthetic_coefficients()), path)
    doc = json.loads(path.read_text())
    doc["size"] = size
    path.write_text(json.dumps(doc).replace("Infinity", "1e400"))
    with pytest.raises(MetadataError, match="damaged"):
        sensors.load(path)
