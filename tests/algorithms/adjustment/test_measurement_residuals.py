"""Residuals of the last adjustment in the block (adjustment/residual_rows.py, block/residuals.py): the control points'
against Adjustment.residuals / .normalised / .ground_residuals, the check points' against an
independent forward intersection (surface.intersection) reprojected with the adjusted models, the
residual_px field on the control_points layer (with load/save of the points still working), and
points removed or renamed since being absent on load."""

import shutil

import numpy as np
import pytest
from osgeo import ogr

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.adjustment.bundle import adjust, check_points
from pushbroom.algorithms.adjustment.residual_rows import residual_rows
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.surface.intersection import Measurements, intersect

CHECK = ["P002", "P005"]


@pytest.fixture
def adjusted(small_scene, small_scene_block, tmp_path):
    """A copy of the small scene's block, 5 control and 2 check points, adjusted (look angles, degree
    0): (block path, Adjustment, check dict, observations)."""
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    obs = cp.import_csv(Block(path), small_scene["points"], suffix="_meas", check_ids=CHECK)
    models = {r["id"]: Block(path).model(r["id"]) for r in Block(path).images()}
    result = adjust(models, obs, ["look:0"], height=300.0)
    check = check_points(result, obs, 300.0)
    return path, result, check, obs


def layer_values(path):
    """{name: residual_px or None} of the control_points layer (None also without the field)."""
    ds = ogr.Open(path)
    layer = ds.GetLayerByName("control_points")
    has = layer.GetLayerDefn().GetFieldIndex("residual_px") >= 0
    return {f["name"]: (f["residual_px"] if has else None) for f in layer}


def test_before_any_adjustment(small_scene_block):
    assert Block(small_scene_block[0]).residuals() == ({}, {})


def test_residuals_are_stored_and_loaded(adjusted, figures):
    path, result, check, obs = adjusted
    assert set(layer_values(path).values()) == {None}
    Block(path).save_residuals(*residual_rows(result, check, obs))
    image, ground = Block(path).residuals()
    ao = result.observations
    names = ao.points["name"]
    # control points: exactly the adjustment's residuals
    control = [n for n in names if n not in CHECK]
    assert len(control) == 5 and sorted(ground) == sorted(control + CHECK)
    for k, m in enumerate(ao.measurements):
        got = image[(names[m["point"]], m["image_id"])]
        assert got == pytest.approx((*result.residuals[k], *result.normalised[k]), abs=1e-12)
    for p, name in enumerate(names):
        v = result.residuals[ao.measurements["point"] == p]
        rms = np.sqrt(np.mean(v * v))
        assert ground[name] == pytest.approx((*result.ground_residuals[p], rms), abs=1e-12)
    # check points: reprojection of an independent intersection with the adjusted models
    chk = obs.subset(np.isin(obs.points["name"], CHECK))
    m = chk.measurements
    models = result.parameters.models
    cut = intersect(models, Measurements(m["image_id"], m["point"], m["col"], m["row"], m["sigma"]), h0=300.0)
    assert cut.ok.all()
    worst = 0.0
    for mk in m:
        p = mk["point"]
        col, row = models[int(mk["image_id"])].ground_to_image(cut.lon[p], cut.lat[p], cut.h[p])
        v = np.array([col - mk["col"], row - mk["row"]])
        got = image[(chk.points["name"][p], mk["image_id"])]
        worst = max(worst, np.abs(np.array(got[:2]) - v).max())
        assert np.isfinite(got[2:]).all() and np.all(np.sign(got[2:]) == np.sign(v))
    assert worst < 1e-3, worst
    for k, name in enumerate(check["names"]):
        p = chk.points["name"].tolist().index(name)
        v = np.array([image[(name, i)][:2] for i in m["image_id"][m["point"] == p]])
        assert ground[name] == pytest.approx(
            (check["dE"][k], check["dN"][k], check["dH"][k], np.sqrt(np.mean(v * v))), abs=1e-9
        )
    assert len(image) == len(ao.measurements) + len(m)
    # the layer field: each point's image RMS
    values = layer_values(path)
    assert values == pytest.approx({n: ground[n][3] for n in names.tolist() + CHECK}, abs=1e-12)
    figures.report(
        "check point image residuals against the reprojection of an independent intersection, max", worst, "px"
    )
    figures.report("residual_px of the point layer", values, "px")


def test_points_load_and_save_with_the_field_and_edits_since(adjusted):
    path, result, check, obs = adjusted
    Block(path).save_residuals(*residual_rows(result, check, obs))
    before = Block(path).control_points()
    assert before.points.tobytes() == obs.points.tobytes()
    store = Block(path).measurement_store()
    store.put_point("NEW", "control", -84.19, 36.615, 300.0, 2.5, 2.5, 2.2)
    store.rename_point("P003", "R3")
    store.delete_point("P004")
    image, ground = Block(path).residuals()
    assert "NEW" not in ground and "R3" not in ground and "P003" not in ground and "P004" not in ground
    assert not any(name in ("P003", "P004", "R3") for name, _ in image)
    assert "P001" in ground and ("P001", 1) in image
    values = layer_values(path)
    assert values["NEW"] is None and values["P001"] == pytest.approx(ground["P001"][3])
    # a merge import and a replace import work on the layer with the field (new features: NULL)
    Block(path).save_control_points(obs, mode="merge")
    assert layer_values(path)["P004"] is None and len(Block(path).control_points().points) == 9
    Block(path).save_control_points(obs)
    assert Block(path).control_points().points.tobytes() == obs.points.tobytes()
    assert set(layer_values(path).values()) == {None}


def test_a_new_adjustment_replaces_the_residuals(adjusted):
    path, result, check, obs = adjusted
    Block(path).save_residuals(*residual_rows(result, check, obs))
    first = Block(path).residuals()
    less = obs.subset(obs.points["name"] != "P001")
    models = {r["id"]: Block(path).model(r["id"]) for r in Block(path).images()}
    again = adjust(models, less, ["look:0"], height=300.0)
    Block(path).save_residuals(*residual_rows(again, check_points(again, less, 300.0), less))
    image, ground = Block(path).residuals()
    assert "P001" not in ground and len(ground) == len(first[1]) - 1
    assert len(image) == len(first[0]) - 3
    assert layer_values(path)["P001"] is None
    ds = ogr.Open(path)
    assert ds.GetLayerByName("measurement_residuals").GetFeatureCount() == len(image)
