"""MeasurementSession (measurement/session.py), the measurement window's state and edits without Qt,
on a block of the marked SPOT 5 triplet: drafts and free names, ground positions and the predictions
of the block's models, provisional points, LSM transfers against the simulator's true positions with
accept/reject, edits with undo and redo through the block, refused edits, imports and exports, and
the residual summaries of the point table. What is on disk is read by a second, fresh session."""

import math
import shutil

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.bundle import adjust, check_points
from pushbroom.algorithms.adjustment.control_points import DEFAULT_SIGMAS
from pushbroom.algorithms.adjustment.residual_rows import residual_rows
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.measurement.session import PROVISIONAL_SIGMA, SIGMA_KEYS, MeasurementSession

#: transfers must land this close (px) to the simulator's true positions
TRANSFER_TOLERANCE = 0.3
CHECK = ("P002", "P005")


class History:
    """The window's undo stack without Qt: the session's recorded edits, `index` the next redo."""

    def __init__(self):
        self.edits, self.index = [], 0

    def record(self, edit):
        del self.edits[self.index :]
        self.edits.append(edit)
        self.index += 1

    def undo(self, session):
        self.index -= 1
        return session.undo(self.edits[self.index])

    def redo(self, session):
        self.index += 1
        return session.redo(self.edits[self.index - 1])

    def texts(self):
        return [edit.text for edit in self.edits[: self.index]]


@pytest.fixture
def dem(marked_scene):
    return read_dem(marked_scene["dsm"])


def open_session(path):
    """(session on `path`, its History)."""
    history = History()
    return MeasurementSession(path, record=history.record), history


def on_disk(path):
    """{name: (put_point values, {image id: (col, row)})} as a fresh session reads the block."""
    fresh = MeasurementSession(path)
    return {
        str(name): (fresh.values(str(name)), {i: m[:2] for i, m in fresh.measurements(str(name)).items()})
        for name in fresh.observations.points["name"]
    }


def ids_by_name(session):
    return {name: i for i, name in session.image_names.items()}


def test_a_new_point_is_a_draft_until_stored(block_path, marked_points):
    session, history = open_session(block_path)
    name = session.new_point()
    assert name == "P001" and session.current == name and session.point(name) is None
    values = session.values(name)
    assert math.isnan(values["lon"]) and [values[k] for k in SIGMA_KEYS] == list(DEFAULT_SIGMAS)
    assert on_disk(block_path) == {} and history.edits == []  # nothing stored yet
    with pytest.raises(InputError, match="no point"):
        session.select_point(name)  # a draft is not in the block
    with pytest.raises(InputError, match="role"):
        session.new_point("X", role="tie")
    assert session.edit_point(name, new_name="D1", role="check") and session.current == "D1"
    assert session.values("D1")["role"] == "check" and history.edits == []  # drafts change in memory
    assert session.delete_point("D1") is False  # discarded, not deleted
    assert session.current is None and session.draft is None
    p = marked_points["P001"]
    session.new_point()
    session.set_ground(p["lon"], p["lat"], p["h"])
    assert session.free_name() == "P002"
    with pytest.raises(InputError, match="exists already"):
        session.new_point("P001")


def test_ground_position_and_predictions(block_path, marked_points):
    """A ground position stores the point with the default sigmas; its predictions are the block
    models' ground_to_image."""
    session, history = open_session(block_path)
    p = marked_points["P003"]
    session.new_point("G1")
    session.set_ground(p["lon"], p["lat"], p["h"])
    values, meas = on_disk(block_path)["G1"]
    assert values == {
        "name": "G1",
        "role": "control",
        "lon": p["lon"],
        "lat": p["lat"],
        "h": p["h"],
        "sigma_e": DEFAULT_SIGMAS[0],
        "sigma_n": DEFAULT_SIGMAS[1],
        "sigma_h": DEFAULT_SIGMAS[2],
    }
    assert meas == {} and history.texts() == ["New point G1"]
    assert session.ground("G1") == (p["lon"], p["lat"], p["h"], False)
    predicted = session.predictions("G1")
    for image_id in session.image_names:
        col, row = Block(block_path).model(image_id).ground_to_image(p["lon"], p["lat"], p["h"])
        assert predicted[image_id] == pytest.approx((float(col), float(row)), abs=1e-9)
    assert session.predictions("nothing") == {} and session.ground(None) is None


def test_transfer_lands_on_the_truth(block_path, marked_points, dem):
    """A point set on the ground (h from the DSM), then measured at its TRUE HRG position: LSM transfers
    into HRS1 and HRS2 are pending within 0.3 px of the true positions (the block's supplied models are
    off by the simulated orientation errors); accepting stores exactly them, rejecting nothing."""
    session, history = open_session(block_path)
    ids = ids_by_name(session)
    for point in ("P001", "P004"):
        p = marked_points[point]
        session.new_point(point)
        session.set_ground(p["lon"], p["lat"], dem.height(p["lon"], p["lat"]))
        session.measure(ids["HRG"], p["HRG_col"], p["HRG_row"], dem=dem)
        results = session.transfer(ids["HRG"], p["HRG_col"], p["HRG_row"])
        assert set(results) == set(session.pending) == {ids["HRS1"], ids["HRS2"]}
        for name in ("HRS1", "HRS2"):
            t = session.pending[ids[name]]
            error = math.hypot(t.col - p[f"{name}_col"], t.row - p[f"{name}_row"])
            assert error < TRANSFER_TOLERANCE, (point, name, error)
            assert 0.7 < t.rho <= 1.0
        pending = dict(session.pending)
        assert on_disk(block_path)[point][1] == {ids["HRG"]: (p["HRG_col"], p["HRG_row"])}  # not yet accepted
        assert session.current_positions() == {
            ids["HRG"]: (p["HRG_col"], p["HRG_row"]),
            **{i: (t.col, t.row) for i, t in pending.items()},
        }
        if point == "P001":
            session.accept_pending(ids["HRS1"])
            assert set(session.pending) == {ids["HRS2"]}
            session.accept_pending()
            meas = on_disk(block_path)[point][1]
            for name in ("HRS1", "HRS2"):
                assert meas[ids[name]] == (pending[ids[name]].col, pending[ids[name]].row)
        else:
            session.reject_pending(ids["HRS2"])
            assert set(session.pending) == {ids["HRS1"]}
            session.reject_pending()
            assert set(on_disk(block_path)[point][1]) == {ids["HRG"]}
            predicted = session.predictions(point)  # no transfer: the views go to the predictions
            assert session.current_positions() == {
                ids["HRG"]: (p["HRG_col"], p["HRG_row"]),
                ids["HRS1"]: predicted[ids["HRS1"]],
                ids["HRS2"]: predicted[ids["HRS2"]],
            }
        assert session.pending == {}
    assert history.texts() == [
        "New point P001",
        "Measure P001 in HRG",
        "Accept transfers of P001",
        "Accept transfers of P001",
        "New point P004",
        "Measure P004 in HRG",
    ]
    assert session.delete_measurement(ids["HRG"]) and not session.delete_measurement(ids["HRG"])
    assert on_disk(block_path)["P004"][1] == {}
    session.select_point("P001")  # another point: its pending transfers are dropped
    assert session.pending == {} and session.transfer_notes == {}


def test_image_first_point_is_provisional(block_path, marked_points, dem):
    """A point measured in an image before it has ground coordinates is stored at once at the ray's
    intersection with the DSM (without a DEM: at the block's mean height), with the provisional sigmas
    (a tie point for the adjustment), in one edit; a later ground position replaces it and restores the
    sigmas chosen before, also across a rename."""
    session, history = open_session(block_path)
    ids = ids_by_name(session)
    model = Block(block_path).model(ids["HRG"])
    p = marked_points["P005"]
    name = session.new_point()
    session.edit_point(name, sigma_e=1.5)
    session.measure(ids["HRG"], p["HRG_col"], p["HRG_row"], dem=dem)
    values, meas = on_disk(block_path)[name]
    lon, lat, h = model.image_to_dem(p["HRG_col"], p["HRG_row"], dem)
    assert (values["lon"], values["lat"], values["h"]) == pytest.approx((float(lon), float(lat), float(h)), abs=1e-9)
    assert [values[k] for k in SIGMA_KEYS] == [PROVISIONAL_SIGMA] * 3 and session.ground(name)[3]
    assert meas == {ids["HRG"]: (p["HRG_col"], p["HRG_row"])}
    assert history.texts() == [f"Measure {name} in HRG"]  # the point and its measurement: one undo step
    session.edit_point(name, new_name="R1")
    session.set_ground(p["lon"], p["lat"], p["h"])
    values, meas = on_disk(block_path)["R1"]
    assert (values["lon"], values["lat"], values["h"]) == (p["lon"], p["lat"], p["h"])
    assert [values[k] for k in SIGMA_KEYS] == [1.5, DEFAULT_SIGMAS[1], DEFAULT_SIGMAS[2]]
    assert meas == {ids["HRG"]: (p["HRG_col"], p["HRG_row"])}
    session.new_point("M1")  # no DEM: the block's mean height
    session.measure(ids["HRG"], p["HRG_col"], p["HRG_row"])
    lon, lat = model.image_to_ground(p["HRG_col"], p["HRG_row"], session.default_height)
    assert session.ground("M1") == pytest.approx((float(lon), float(lat), session.default_height, True), abs=1e-9)


def test_edit_rename_delete_undo_redo(block_path, marked_points):
    """Role, sigmas and name edits and a delete go through the block at once; undo/redo walk the block
    through the same states, and the current point follows a rename's undo."""
    session, history = open_session(block_path)
    ids = ids_by_name(session)
    p = marked_points["P001"]
    session.new_point("A")
    session.set_ground(p["lon"], p["lat"], p["h"])
    session.measure(ids["HRG"], p["HRG_col"], p["HRG_row"])
    session.measure(ids["HRS1"], p["HRS1_col"], p["HRS1_row"])
    states = [on_disk(block_path)]
    session.edit_point("A", role="check", sigma_h=4.0)
    values, meas = on_disk(block_path)["A"]
    assert values["role"] == "check" and values["sigma_h"] == 4.0 and len(meas) == 2
    states.append(on_disk(block_path))
    session.edit_point("A", new_name="B")
    assert set(on_disk(block_path)) == {"B"} and session.current == "B"
    assert on_disk(block_path)["B"][1] == meas
    states.append(on_disk(block_path))
    session.delete_point("B")
    assert on_disk(block_path) == {} and session.current is None
    states.append(on_disk(block_path))
    assert history.texts()[-3:] == ["Edit point A", "Edit point A", "Delete point B"]
    for k in range(3):  # undo the delete, the rename, the edit
        assert history.undo(session) == []
        assert on_disk(block_path) == states[-2 - k]
    history.undo(session)  # the HRS1 measurement
    assert set(on_disk(block_path)["A"][1]) == {ids["HRG"]}
    history.redo(session)
    for k in range(3):  # redo the edit, the rename, the delete
        assert history.redo(session) == []
        assert on_disk(block_path) == states[1 + k]
    history.undo(session)  # the delete again: the point is back with its measurements
    assert on_disk(block_path)["B"][1] == meas
    session.select_point("B")
    history.undo(session)  # the rename: the current point is A again
    assert session.current == "A" and set(on_disk(block_path)) == {"A"}
    for _ in range(4):  # the edit, both measurements, the point's creation
        history.undo(session)
    assert on_disk(block_path) == {} and session.current is None


def test_refused_edits_change_nothing(block_path, marked_points):
    """A refused edit raises the engine's error, changes nothing and records nothing; an edit failing
    midway records the part done, which undo takes back."""
    session, history = open_session(block_path)
    ids = ids_by_name(session)
    p = marked_points["P001"]
    for name in ("A", "B"):
        session.new_point(name)
        session.set_ground(p["lon"], p["lat"], p["h"])
    before, steps = on_disk(block_path), len(history.edits)
    with pytest.raises(InputError, match="exists already"):
        session.edit_point("B", new_name="A")
    with pytest.raises(InputError, match="outside image"):
        session.measure(ids["HRG"], -5.0, 10.0)
    with pytest.raises(InputError, match="no image with id 99"):
        session.measure(99, 1.0, 1.0)
    assert on_disk(block_path) == before and len(history.edits) == steps
    with pytest.raises(InputError, match="characters"):
        session.edit_point("B", new_name="N" * 33, role="check")  # the role is stored, the rename refused
    assert on_disk(block_path)["B"][0]["role"] == "check" and history.texts()[-1] == "Edit point B"
    assert len(history.edits[-1].commands) == 1
    history.undo(session)
    assert on_disk(block_path) == before


def test_csv_and_georeferencer_round_trips(block_path, marked_scene, marked_block, marked_points, dem, tmp_path):
    """Export CSV, import into a fresh block: the same points; export the HRS1 measurements as a
    Georeferencer .points file, import it into another block: one point per measurement at the same
    map position and pixel, heights from the DSM. Each import is one undo step."""
    session, _ = open_session(block_path)
    ids = ids_by_name(session)
    session.import_csv(marked_scene["points"], suffix="_meas")
    session.export_csv(tmp_path / "out.csv")
    session.export_points_file(tmp_path / "hrs1.points", ids["HRS1"], crs="EPSG:4326")
    other = str(shutil.copy(marked_block, tmp_path / "other.gpkg"))
    second, history = open_session(other)
    second.import_csv(tmp_path / "out.csv")
    original = on_disk(block_path)
    assert on_disk(other) == original and history.texts() == ["Import out.csv"]
    for name in list(original):
        second.delete_point(name)
    read = second.import_points_file(tmp_path / "hrs1.points", ids["HRS1"], dem=dem)
    got = on_disk(other)
    assert len(read.points) == len(got) == len(marked_points)
    by_pixel = {meas[ids["HRS1"]]: values for values, meas in got.values()}
    for values, meas in original.values():
        q = by_pixel[meas[ids["HRS1"]]]
        assert (q["lon"], q["lat"]) == pytest.approx((values["lon"], values["lat"]), abs=1e-8)
        assert q["h"] == pytest.approx(dem.height(q["lon"], q["lat"]), abs=1e-6)
    history.undo(second)  # the .points import
    assert on_disk(other) == {}
    with pytest.raises(InputError, match="cannot read"):
        second.import_points_file(tmp_path / "missing.points", ids["HRS1"], dem=dem)


def test_point_summaries_and_residuals(block_path, marked_scene, marked_points):
    """The point table's rows: per point its role, h, the images measured in and, after an adjustment
    stored in the block, per image |v| and |w| of its residual and its ground residuals; residual
    lookups for the views."""
    session, _ = open_session(block_path)
    ids = ids_by_name(session)
    obs = session.import_csv(marked_scene["points"], suffix="_meas", check_ids=CHECK)
    rows = session.point_summaries()
    assert [r["name"] for r in rows] == list(marked_points)
    for r in rows:
        role = "check" if r["name"] in CHECK else "control"
        assert (r["role"], r["count"], r["measured"]) == (role, 3, set(ids.values()))
        assert r["h"] == pytest.approx(marked_points[r["name"]]["h"], abs=1e-9)
        assert r["images"] == dict.fromkeys(ids.values()) and r["ground"] is None  # not adjusted yet
    hrg = sorted(session.measured_in(ids["HRG"]))
    assert hrg == sorted((n, p["HRG_col_meas"], p["HRG_row_meas"]) for n, p in marked_points.items())
    models = {i: Block(block_path).model(i) for i in session.image_names}
    height = float(np.mean(Block(block_path).height_range()))
    result = adjust(models, obs, ["look:0"], height=height)
    Block(block_path).save_residuals(*residual_rows(result, check_points(result, obs, height), obs))
    session.adjusted()
    image_res, ground = Block(block_path).residuals()
    for r in session.point_summaries():
        assert r["ground"] == ground[r["name"]]
        for image_id in ids.values():
            vx, vy, wx, wy = image_res[(r["name"], image_id)]
            assert r["images"][image_id] == (math.hypot(vx, vy), max(abs(wx), abs(wy)))
            assert session.image_residual(r["name"], image_id) == (vx, vy, wx, wy)
    assert session.residual_px() == {name: g[3] for name, g in ground.items()}
    assert session.image_residual("nothing", ids["HRG"]) is None
