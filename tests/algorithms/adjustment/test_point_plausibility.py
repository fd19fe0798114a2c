"""Control points checked against the block's image footprints at import (point_plausibility.py): the
mistakes a user makes with coordinates are named and refused, true points pass."""

import csv
import re
import shutil

import numpy as np
import pytest
from scipy.stats import chi2

from pushbroom.algorithms.adjustment import control_points as cp, point_plausibility
from pushbroom.algorithms.adjustment.point_plausibility import MARGIN_M, distance_to_polygon
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.geodesy import metres_per_degree, utm_epsg
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
    assert len(Block(blk).control_points().points) == len(before.points) == 0  # nothing imported


def test_a_point_ten_degrees_off_is_named(blk, rows, tmp_path):
    rows[5]["lon"] = str(float(rows[5]["lon"]) + 10.0)
    with pytest.raises(InputError, match=rf"1 point\(s\).*{rows[5]['id']}: lies \d+\.\d km outside every image"):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def test_degrees_given_as_utm_x_y_are_named(blk, rows, tmp_path):
    epsg = utm_epsg(float(rows[0]["lon"]), float(rows[0]["lat"]))
    path = write_rows(tmp_path / "p.csv", rows, rename={"lon": "x", "lat": "y"})
    with pytest.raises(InputError, match="x/y look like degrees, not coordinates of the projected CRS"):
        cp.import_csv(Block(blk), path, suffix="_meas", crs=f"EPSG:{epsg}")


def test_a_measurement_of_another_point_is_named(blk, rows, tmp_path):
    # P001's HRG measurement replaced by the farthest point's: its HRG ray misses where its HRS rays meet
    far = max(
        range(1, len(rows)),
        key=lambda k: np.hypot(
            float(rows[k]["HRG_col_meas"]) - float(rows[0]["HRG_col_meas"]),
            float(rows[k]["HRG_row_meas"]) - float(rows[0]["HRG_row_meas"]),
        ),
    )
    rows[0]["HRG_col_meas"], rows[0]["HRG_row_meas"] = rows[far]["HRG_col_meas"], rows[far]["HRG_row_meas"]
    with pytest.raises(
        InputError,
        match=rf"{rows[0]['id']}: its rays do not meet: the one of its measurement in HRG "
        r"at .* passes \d+ m from where the others meet",
    ):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def where_rays_meet(message):
    """(height difference, horizontal distance) in metres of the rays' meeting point from the point's coordinates,
    as the refusal states them."""
    found = re.search(r"meet (\d+) m (above|below) its height [-0-9.]+ m and (\d+) m beside its position", message)
    assert found, message
    return float(found.group(1)) * (1 if found.group(2) == "above" else -1), float(found.group(3))


def test_a_point_3000_m_too_high_is_refused_with_where_its_rays_meet(blk, rows, tmp_path):
    # SPOT 5's HRS rays view 20 degrees fore and aft: 3000 m of height move them 1100 m apart, twenty times the
    # 50 m the orientation is stated to; 300 m (120 m on the ground) lies within it
    rows[1]["h"] = str(float(rows[1]["h"]) + 3000.0)
    with pytest.raises(InputError, match=rf"^1 point\(s\).*{rows[1]['id']}: its measurements meet") as err:
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")
    dh, across = where_rays_meet(str(err.value))
    # the rays meet 3000 m below, to within the supplied orientation's errors (about 30 m on the ground,
    # perturbation.py; a few times that in height at the triplet's B/H)
    assert abs(dh + 3000.0) < 200.0 and across < 100.0
    assert Block(blk).control_points().points.size == 0  # nothing imported


def test_a_point_one_km_off_is_refused(blk, rows, tmp_path):
    # 1 km lies within the footprints' 2 km margin, but twenty times the orientation's stated 50 m
    rows[2]["lat"] = str(float(rows[2]["lat"]) + 1000.0 / metres_per_degree(float(rows[2]["lat"]))[1])
    with pytest.raises(InputError, match=rf"{rows[2]['id']}: its measurements meet") as err:
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")
    dh, across = where_rays_meet(str(err.value))
    assert abs(across - 1000.0) < 100.0 and abs(dh) < 200.0  # the 1 km, to within the supplied errors


def test_a_point_measured_in_one_image_far_from_its_projection_is_named(blk, rows, tmp_path):
    # one ray: no intersection, its offset alone against the HRG model's 50 m
    for image in ("HRS1", "HRS2"):
        rows[3][f"{image}_col_meas"] = rows[3][f"{image}_row_meas"] = ""
    rows[3]["lon"] = str(float(rows[3]["lon"]) + 800.0 / metres_per_degree(float(rows[3]["lat"]))[0])
    with pytest.raises(
        InputError,
        match=rf"{rows[3]['id']}: measured in HRG at .*, 0\.[78] km from where its "
        "coordinates project",
    ):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def test_a_height_off_the_earth_is_named(blk, rows, tmp_path):
    rows[4]["h"] = "60000"
    with pytest.raises(
        InputError,
        match=rf"^1 point\(s\).*{rows[4]['id']}: its height 60000 m lies outside the "
        r"heights of terrain on Earth \(-500 \.\. 9000 m\)",
    ):
        cp.import_csv(Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas")


def test_the_simulated_points_agree_with_their_measurements_far_within_the_bound(small_scene_block, rows, tmp_path):
    # the consistency statistic of the true points (supplied orientation off by about 30 m, perturbation.py)
    # against its chi-square bound: at SPOT 5's stated 50 m they use a small part of it
    blk = Block(small_scene_block[0])
    obs = cp.read_csv(
        write_rows(tmp_path / "p.csv", rows), {r["name"]: r["id"] for r in blk.images()}, cp.CsvOptions(suffix="_meas")
    )
    footprints = point_plausibility.Footprints(
        blk.models(), {r["id"]: r["name"] for r in blk.images()}, list(blk.height_range())
    )
    offset, _, sigma = footprints.rays(obs)
    per_point = np.bincount(obs.measurements["point"], (offset**2).sum(axis=1) / sigma**2)
    bound = chi2.isf(point_plausibility.FALSE_ALARM, 6)  # three rays each (scipy.stats: the module uses chdtri)
    assert np.all(sigma == pytest.approx(50.0, abs=2.0))  # SPOT 5's 50 m and 0.5 px of 5-10 m
    assert per_point.max() < 0.25 * bound


def test_kept_on_request_with_a_warning(blk, rows, tmp_path):
    rows[2]["lat"] = str(float(rows[2]["lat"]) - 10.0)
    log = Feedback()
    obs = cp.import_csv(
        Block(blk), write_rows(tmp_path / "p.csv", rows), suffix="_meas", keep_implausible=True, feedback=log
    )
    assert len(obs.points) == len(rows)
    assert any(m.startswith("warning: kept 1 point(s)") and rows[2]["id"] in m for m in log.messages)
    assert Block(blk).info()["control_points"] == str(len(rows))


def test_margin_is_kilometres():
    # the margin must exceed any supplied-orientation error the adjustment handles (1 km) and stay far below
    # the errors it exists to catch (a 10 degree slip is about 1000 km)
    assert 1000.0 < MARGIN_M < 10000.0
