"""MeasurementStore: single edits of a block's control/check points and measurements, each one
committed SQLite transaction (read back with OGR and control_points.load_control_points), refused
edits and failures that leave the block as it was, and edits surviving a killed process."""

import shutil
import subprocess
import sys

import pytest
from osgeo import ogr

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block, control_points as stored_points
from pushbroom.algorithms.errors import InputError, StorageError

POINT = dict(name="N1", role="check", lon=-84.19, lat=36.615, h=310.5, sigma_e=1.5, sigma_n=1.25, sigma_h=2.0)


@pytest.fixture
def blk(small_scene, small_scene_block, tmp_path):
    """A copy of the small scene's block with the simulator's 7 points and their measurements."""
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    cp.import_csv(Block(path), small_scene["points"], suffix="_meas")
    return path


def same(a, b):
    return a.points.tobytes() == b.points.tobytes() and a.measurements.tobytes() == b.measurements.tobytes()


def stored(path):
    """(points {name: (role, x, y, z, sigmas)} from the layer's features and geometry, measurements
    {(name, image id): (col, row, sigma)}) read with plain OGR."""
    ds = ogr.Open(path)
    points = {}
    for f in ds.GetLayerByName("control_points"):
        points[f["name"]] = (f["role"], *f.GetGeometryRef().GetPoint(), f["sigma_e"], f["sigma_n"], f["sigma_h"])
    meas = {
        (f["point_name"], f["image_id"]): (f["col"], f["row"], f["sigma"])
        for f in ds.GetLayerByName("image_measurements")
    }
    return points, meas


def counts(path):
    info = Block(path).info()
    return tuple(int(info[k]) for k in ("control_points", "check_points", "image_measurements"))


def test_edits_are_stored_at_once(blk):
    store = Block(blk).measurement_store()
    before = store.load()
    assert len(before.points) == 7 and len(before.measurements) == 21 and counts(blk) == (7, 0, 21)
    assert store.put_point(**POINT) is None
    points, meas = stored(blk)
    assert points["N1"] == ("check", POINT["lon"], POINT["lat"], POINT["h"], 1.5, 1.25, 2.0)
    assert counts(blk) == (7, 1, 21)
    assert store.put_measurement("N1", 1, 120.25, 300.5) is None
    assert store.put_measurement("N1", 3, 60.0, 301.0, sigma=0.3) is None
    old = store.put_measurement("N1", 1, 121.0, 299.0)
    assert old.tolist() == (0, 1, 120.25, 300.5, 0.5)
    _, meas = stored(blk)
    assert meas[("N1", 1)] == (121.0, 299.0, 0.5) and meas[("N1", 3)] == (60.0, 301.0, 0.3)
    assert counts(blk) == (7, 1, 23)
    # update keeps the measurements; the earlier record comes back
    old = store.put_point(**dict(POINT, role="control", h=311.0))
    assert old["role"] == "check" and old["h"] == 310.5
    obs = store.load()
    k = obs.points["name"].tolist().index("N1")
    assert obs.points[k]["role"] == "control" and obs.points[k]["h"] == 311.0
    assert sorted(obs.measurements["image_id"][obs.measurements["point"] == k].tolist()) == [1, 3]
    assert counts(blk) == (8, 0, 23)
    # rename: the measurements follow
    store.rename_point("N1", "N2")
    points, meas = stored(blk)
    assert "N1" not in points and "N2" in points
    assert meas[("N2", 1)] == (121.0, 299.0, 0.5) and not any(name == "N1" for name, _ in meas)
    # delete and restore give back exactly the block before
    snapshot = store.load()
    record, removed = store.delete_point("N2")
    assert record["name"] == "N2" and removed["image_id"].tolist() == [1, 3] and (removed["point"] == 0).all()
    assert "N2" not in stored(blk)[0] and counts(blk) == (7, 0, 21)
    assert same(store.load(), before)
    store.restore(record, removed)
    assert same(store.load(), snapshot) and counts(blk) == (8, 0, 23)
    # delete a measurement
    gone = store.delete_measurement("N2", 3)
    assert gone.tolist() == (0, 3, 60.0, 301.0, 0.3)
    assert store.delete_measurement("N2", 3) is None and store.delete_measurement("nobody", 1) is None
    assert ("N2", 3) not in stored(blk)[1] and counts(blk) == (8, 0, 22)
    # no run_log row per edit
    ds = ogr.Open(blk)
    assert [f["step"] for f in ds.GetLayerByName("run_log")] == ["createblock", "importpoints"]


def test_snapshot_restores_an_edited_point(blk):
    store = Block(blk).measurement_store()
    before = store.load()
    snap = store.snapshot("P003")
    assert snap[0]["name"] == "P003" and snap[1]["image_id"].tolist() == [1, 2, 3]
    store.put_point(**dict(POINT, name="P003"))
    store.put_measurement("P003", 2, 10.0, 20.0)
    store.delete_measurement("P003", 3)
    store.restore(*snap)
    after = store.load()
    assert same(after, before)
    assert store.snapshot("nobody") is None


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda s: s.put_point(**dict(POINT, name="")), "1 to 32 printable characters"),
        (lambda s: s.put_point(**dict(POINT, name="x" * 33)), "1 to 32 printable characters"),
        (lambda s: s.put_point(**dict(POINT, name="N1\x00")), "1 to 32 printable characters"),
        (lambda s: s.put_point(**dict(POINT, name=" N1")), "spaces"),
        (lambda s: s.put_point(**dict(POINT, role="tie")), "role must be one of control, check"),
        (lambda s: s.put_point(**dict(POINT, lon=float("nan"))), "finite"),
        (lambda s: s.put_point(**dict(POINT, h=float("inf"))), "finite"),
        (lambda s: s.put_point(**dict(POINT, lat=91.0)), "not WGS 84 degrees"),
        (lambda s: s.put_point(**dict(POINT, sigma_n=0.0)), "sigmas east, north, height must be positive"),
        (lambda s: s.put_point(**dict(POINT, sigma_h=-1.0)), "must be positive"),
        (lambda s: s.rename_point("P001", "P002"), "P002 exists already"),
        (lambda s: s.rename_point("nobody", "P099"), "no point 'nobody'"),
        (lambda s: s.rename_point("P001", ""), "1 to 32 printable characters"),
        (lambda s: s.delete_point("nobody"), "no point 'nobody'"),
        (lambda s: s.put_measurement("nobody", 1, 10.0, 10.0), "no point 'nobody'"),
        (lambda s: s.put_measurement("P001", 9, 10.0, 10.0), "no image with id 9"),
        (lambda s: s.put_measurement("P001", 2, 301.0, 10.0), r"outside image HRS1 \(300 x 599 px\)"),
        (lambda s: s.put_measurement("P001", 1, 10.0, -0.5), "outside image HRG"),
        (lambda s: s.put_measurement("P001", 1, float("nan"), 1.0), "outside image HRG"),
        (lambda s: s.put_measurement("P001", 1, 10.0, 10.0, sigma=0.0), "sigma must be positive"),
    ],
)
def test_refused_edits_leave_the_block_unchanged(blk, call, message):
    store = Block(blk).measurement_store()
    before, files = store.load(), stored(blk)
    with pytest.raises(InputError, match=message):
        call(store)
    assert same(store.load(), before) and stored(blk) == files and counts(blk) == (7, 0, 21)


def test_a_failure_inside_the_transaction_rolls_back(blk, monkeypatch):
    """restore() fails while writing its second measurement (an OGR error): nothing of it is stored."""
    store = Block(blk).measurement_store()
    record, removed = store.delete_point("P002")
    before, files = store.load(), stored(blk)
    written = []

    def failing(table, name, m):
        if written:
            raise RuntimeError("disk I/O error")
        written.append(m)
        real(table, name, m)

    real = stored_points.write_measurement
    monkeypatch.setattr(stored_points, "write_measurement", failing)
    with pytest.raises(StorageError, match="cannot store the edit in the block .*disk I/O error"):
        store.restore(record, removed)
    assert written and same(store.load(), before) and stored(blk) == files and counts(blk) == (6, 0, 18)


def test_edits_survive_a_killed_process(blk):
    """A process that edits and is then killed (SIGKILL, no clean-up) leaves every returned edit in the block."""
    code = (
        "import os, signal, sys\n"
        "from pushbroom.algorithms.block import Block\n"
        "s = Block(sys.argv[1]).measurement_store()\n"
        "s.put_point('K1', 'control', -84.19, 36.615, 300.0, 2.5, 2.5, 2.2)\n"
        "s.put_measurement('K1', 2, 150.5, 200.25)\n"
        "s.delete_measurement('P001', 1)\n"
        "s.rename_point('P002', 'R2')\n"
        "sys.stdout.write('edited\\n')\n"
        "sys.stdout.flush()\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    run = subprocess.run([sys.executable, "-c", code, blk], capture_output=True, text=True, timeout=120)
    assert run.returncode == -9 and "edited" in run.stdout
    points, meas = stored(blk)
    assert "K1" in points and "R2" in points and "P002" not in points
    assert meas[("K1", 2)] == (150.5, 200.25, 0.5) and ("P001", 1) not in meas and ("R2", 3) in meas
    assert counts(blk) == (8, 0, 21)
    assert len(Block(blk).measurement_store().load().points) == 8


def test_an_edit_waits_for_another_writer(blk):
    """Another connection holds a write transaction (QGIS saving the layer, an adjustment storing its
    models): the edit waits for its commit instead of failing."""
    code = (
        "import sys, time\n"
        "from osgeo import ogr\n"
        "ogr.UseExceptions()\n"
        "ds = ogr.Open(sys.argv[1], 1)\n"
        "ds.StartTransaction()\n"
        "ds.ExecuteSQL(\"UPDATE block_info SET value = 'held' WHERE key = 'default_crs'\")\n"
        "sys.stdout.write('holding\\n')\n"
        "sys.stdout.flush()\n"
        "time.sleep(1.0)\n"
        "ds.CommitTransaction()\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code, blk], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "holding"
        Block(blk).measurement_store().put_point(**POINT)
    finally:
        holder.wait(timeout=60)
    assert Block(blk).info()["default_crs"] == "held" and "N1" in stored(blk)[0]
