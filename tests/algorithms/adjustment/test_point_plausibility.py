"""Control points checked against the block's image footprints at import (point_plausibility.py): the
mistakes a user makes with coordinates are named and refused, true points pass."""
import csv
import shutil

import numpy as np
import pytest

from pushbroom.algorithms.adjustment import control_points as cp, point_plausibility
from pushbroom.algorithms.adjustment.point_plausibility import MARGIN_M, distance_to_polygon
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.geodesy import utm_epsg
from tests.helpers.feedback import Feedback


@pytest.fixture
def blk(small_scene_block, tmp_path):
    path = tmp_path / "block.gpkg"
    shutil.copy(small_scene_block[0], path)
    return str(path)


@pytest.fixture
def rows(small_scene_block):
    return [dict(r) for r in small_scene_block[1]]


def write_rows(path, rows, rename=None):
    rename = rename or {}
    header = [rename.get(k, k) for k in rows[0]]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows([list(r.values()) for r in rows])
    return str(path)


def test_distance_to_polygon_against_a_square():
    ring = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]])
    d = distance_to_polygon([5.0, 13.0, -3.0, 14.0], [5.0, 5.0, 5.0, 14.0], ring)
    # inside, 3 east, 3 west, the corner at (4, 4) away
    np.testing.assert_allclose(d, [0.0, 3.0, 3.0, np.hypot(4.0, 4.0)])


def test_the_simulated_points_pass(blk, rows, tmp_path):
    # every simulated candidate lies on the images and is measured where its coordinates project
    obs = cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")
    assert len(obs.points) == len(rows)


def test_swapped_lon_lat_is_named_and_refused(blk, rows, tmp_path):
    rows[3]["lon"], rows[3]["lat"] = rows[3]["lat"], rows[3]["lon"]
    before = Block(blk).control_points()
    with pytest.raises(InputError, match=rf"{rows[3]['id']}: lon .* and lat .* look swapped"):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")
    assert len(Block(blk).control_points().points) == len(before.points) == 0      # nothing imported


def test_a_point_ten_degrees_off_is_named(blk, rows, tmp_path):
    rows[5]["lon"] = str(float(rows[5]["lon"]) + 10.0)
    with pytest.raises(InputError, match=rf"1 point\(s\).*{rows[5]['id']}: lies \d+\.\d km outside every image"):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def test_degrees_given_as_utm_x_y_are_named(blk, rows, tmp_path):
    epsg = utm_epsg(float(rows[0]["lon"]), float(rows[0]["lat"]))
    path = write_rows(tmp_path / "p.csv", rows, rename={"lon": "x", "lat": "y"})
    with pytest.raises(InputError, match="x/y look like degrees, not coordinates of the projected CRS"):
        cp.import_csv(Block(blk), path, suffix="_meas", crs=f"EPSG:{epsg}")


def test_a_measurement_of_another_point_is_named(blk, rows, tmp_path, monkeypatch):
    # the small scene is 3 km across, the margin 2 km: a smaller margin lets the farthest point's
    # measurement (over 1 km away in a 3 km scene) stand for a wrong one
    monkeypatch.setattr(point_plausibility, "MARGIN_M", 500.0)
    far = max(range(1, len(rows)),
              key=lambda k: np.hypot(float(rows[k]["HRG_col_meas"]) - float(rows[0]["HRG_col_meas"]),
                                     float(rows[k]["HRG_row_meas"]) - float(rows[0]["HRG_row_meas"])))
    rows[0]["HRG_col_meas"], rows[0]["HRG_row_meas"] = rows[far]["HRG_col_meas"], rows[far]["HRG_row_meas"]
    with pytest.raises(InputError, match=rf"{rows[0]['id']}: measured in HRG at .* km from where its coordinates"):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def test_kept_on_request_with_a_warning(blk, rows, tmp_path):
    rows[2]["lat"] = str(float(rows[2]["lat"]) - 10.0)
    log = Feedback()
    obs = cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas", keep_implausible=True,
                        feedback=log)
    assert len(obs.points) == len(rows)
    assert any(m.startswith("warning: kept 1 point(s)") and rows[2]["id"] in m for m in log.messages)
    assert Block(blk).info()["control_points"] == str(len(rows))


def test_margin_is_kilometres():
    # the margin must exceed any supplied-orientation error the adjustment handles (1 km) and stay far below
    # the errors it exists to catch (a 10 degree slip is about 1000 km)
    assert 1000.0 < MARGIN_M < 10000.0
