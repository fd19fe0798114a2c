"""pushbroom:importpoints and pushbroom:exportpoints on a small simulated SPOT-5 triplet."""

import csv
import shutil

import numpy as np
import pytest
from qgis import processing
from qgis.core import (
    QgsCategorizedSymbolRenderer,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProject,
    QgsVectorLayer,
)

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.geodesy import utm_epsg
from pushbroom.plugin.algorithms.import_points import ExportPoints, ImportPoints
from tests.helpers.osr_oracle import utm


@pytest.fixture
def scene(small_scene, small_scene_block):
    return {"points": small_scene["points"], "rows": small_scene_block[1], "template": small_scene_block[0]}


@pytest.fixture
def algorithms(pushbroom_provider):
    """The provider lists both algorithms."""
    for cls in (ImportPoints, ExportPoints):
        assert pushbroom_provider.algorithm(cls.NAME) is not None
    return pushbroom_provider


@pytest.fixture
def blk(scene, tmp_path):
    path = tmp_path / "block.gpkg"
    shutil.copy(scene["template"], path)
    return str(path)


def test_import_simulator_points_and_export(algorithms, scene, blk, tmp_path, log):
    rows = scene["rows"]
    context, log = QgsProcessingContext(), log
    context.setProject(QgsProject.instance())
    result = processing.run(
        "pushbroom:importpoints",
        {"BLOCK": blk, "INPUT": scene["points"], "MEAS_SUFFIX": "_meas", "CHECK_IDS": "P002, P005"},
        context=context,
        feedback=log,
    )
    n = len(rows)
    assert (result["CONTROL"], result["CHECK"], result["MEASUREMENTS"]) == (n - 2, 2, 3 * n)
    assert any(
        m.startswith(f"points in the block: control {n - 2}, check 2; HRG: {n - 2} control, 2 check")
        for m in log.messages
    ), log.messages
    assert any("ignored column" in m for m in log.messages)
    assert not any("CRS applies" in m for m in log.messages)  # the CRS defaults to WGS 84
    layer = QgsVectorLayer(result["POINTS"], "points", "ogr")
    assert layer.isValid() and layer.featureCount() == n and layer.crs().authid() == "EPSG:4326"
    by_name = {f["name"]: f for f in layer.getFeatures()}
    for r in rows:
        feat = by_name[r["id"]]
        point = feat.geometry().constGet()
        assert (point.x(), point.y(), point.z()) == (float(r["lon"]), float(r["lat"]), float(r["h"]))
        assert feat["role"] == ("check" if r["id"] in ("P002", "P005") else "control")
    # loaded on completion with the role style
    details = context.layersToLoadOnCompletion()[result["POINTS"]]
    details.postProcessor().postProcessLayer(layer, context, log)
    assert isinstance(layer.renderer(), QgsCategorizedSymbolRenderer) and layer.renderer().classAttribute() == "role"
    out = tmp_path / "export.csv"
    exported = processing.run("pushbroom:exportpoints", {"BLOCK": blk, "OUTPUT": str(out)})
    assert exported["OUTPUT"] == str(out)
    back = cp.read_csv(out, Block(blk).image_ids())
    stored = Block(blk).control_points()
    assert back.points.tobytes() == stored.points.tobytes()
    assert back.measurements.tobytes() == stored.measurements.tobytes()


def test_import_projected_coordinates_and_merge(algorithms, scene, blk, tmp_path):
    rows = scene["rows"]
    lon, lat = np.array([float(r["lon"]) for r in rows]), np.array([float(r["lat"]) for r in rows])
    epsg = utm_epsg(lon.mean(), lat.mean())
    xy = utm(lon, lat, epsg).T
    path = tmp_path / "utm.csv"
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "role", "x", "y", "h", "HRS1_col", "HRS1_row"])
        for r, (x, y) in zip(rows, xy):
            writer.writerow([r["id"], "check", repr(x), repr(y), r["h"], r["HRS1_col_meas"], r["HRS1_row_meas"]])
    processing.run("pushbroom:importpoints", {"BLOCK": blk, "INPUT": scene["points"], "MEAS_SUFFIX": "_meas"})
    result = processing.run(
        "pushbroom:importpoints", {"BLOCK": blk, "INPUT": str(path), "CRS": f"EPSG:{epsg}", "MODE": 1}
    )
    assert (result["CONTROL"], result["CHECK"], result["MEASUREMENTS"]) == (0, len(rows), 3 * len(rows))
    stored = Block(blk).control_points()
    assert np.abs(stored.points["lon"] - lon).max() < 1e-8 and np.abs(stored.points["lat"] - lat).max() < 1e-8


def test_a_file_without_measurements_keeps_the_measured_points(algorithms, scene, blk, tmp_path, log):
    """Issue 36: a CSV without measurement columns replaced the block's measured points by one unmeasured
    point. Now it is refused and the block keeps them; REPLACE_FEWER replaces them, with a warning."""
    processing.run("pushbroom:importpoints", {"BLOCK": blk, "INPUT": scene["points"], "MEAS_SUFFIX": "_meas"})
    before = Block(blk).control_points()
    row = scene["rows"][0]
    bare = tmp_path / "bare.csv"
    bare.write_text(f"id,lon,lat,h\n{row['id']},{row['lon']},{row['lat']},{row['h']}\n")
    n = len(scene["rows"])
    with pytest.raises(QgsProcessingException, match=rf"0 image measurements against {3 * n}.*REPLACE_FEWER"):
        processing.run("pushbroom:importpoints", {"BLOCK": blk, "INPUT": str(bare)})
    after = Block(blk).control_points()
    assert after.points.tobytes() == before.points.tobytes()
    assert after.measurements.tobytes() == before.measurements.tobytes()
    result = processing.run(
        "pushbroom:importpoints", {"BLOCK": blk, "INPUT": str(bare), "REPLACE_FEWER": True}, feedback=log
    )
    assert (result["CONTROL"], result["CHECK"], result["MEASUREMENTS"]) == (1, 0, 0)
    assert any("far fewer" in w for w in log.warnings)


def test_bad_file_is_a_processing_error(algorithms, scene, blk, tmp_path):
    processing.run("pushbroom:importpoints", {"BLOCK": blk, "INPUT": scene["points"], "MEAS_SUFFIX": "_meas"})
    before = Block(blk).control_points()
    bad = tmp_path / "bad.csv"
    bad.write_text("id,lon,lat,h,SPOT4_col,SPOT4_row\nA,-84.2,36.6,300,1,2\n")
    with pytest.raises(QgsProcessingException, match="SPOT4_col, SPOT4_row name images that are not in the block"):
        processing.run("pushbroom:importpoints", {"BLOCK": blk, "INPUT": str(bad)})
    assert Block(blk).control_points().points.tobytes() == before.points.tobytes()
    empty = tmp_path / "empty.gpkg"
    shutil.copy(scene["template"], empty)
    with pytest.raises(QgsProcessingException, match="no control or check points"):
        processing.run("pushbroom:exportpoints", {"BLOCK": str(empty), "OUTPUT": str(tmp_path / "out.csv")})
