"""The block stays consistent when a store is killed (kill -9 of a subprocess) or meets another writer: the
point layer, the point file and the counts are the old ones or the new ones, never a mix; generations
count every change of the control points, also one made with plain SQL as QGIS's attribute table would."""

import csv
import pathlib
import shutil
import sqlite3
import subprocess
import sys
import time

import pytest
from osgeo import ogr

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block, schema
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.errors import StorageError
from tests.helpers.points_synthetic import FlatModel, two_ray_points

REPO = pathlib.Path(__file__).resolve().parents[3]
STORE = """
import sys
import numpy as np
from pushbroom.algorithms.block import Block
from tests.helpers.points_synthetic import FlatModel, two_ray_points
sys.stdout.write("storing\\n")
sys.stdout.flush()
points = two_ray_points(int(sys.argv[2]), np.random.default_rng(0))
Block(sys.argv[1]).store_points(points, display=(FlatModel(), 1, 0.0))
sys.stdout.write("stored\\n")
sys.stdout.flush()
"""


def tables(path):
    with sqlite3.connect(path) as db:
        return {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}


def layer_rows(path, name="mass_points"):
    with sqlite3.connect(path) as db:
        return db.execute(f'SELECT COUNT(*) FROM "{name}"').fetchone()[0]


@pytest.fixture
def blk(tmp_path):
    path = tmp_path / "b.gpkg"
    create_schema(path)
    Block(path).store_points(two_ray_points(1000), display=(FlatModel(), 1, 0.0))
    return str(path)


def test_a_store_killed_while_it_builds_the_layer_leaves_the_old_points(blk, tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", STORE, blk, "1500000"], stdout=subprocess.PIPE, text=True, cwd=REPO)
    assert proc.stdout.readline().strip() == "storing"
    deadline = time.time() + 300
    while not any(t.startswith("mass_points__staged_") for t in tables(blk)):  # the new layer is being built
        assert proc.poll() is None and time.time() < deadline, "the store ended before it built its layer"
        time.sleep(0.02)
    time.sleep(0.5)
    proc.kill()
    proc.wait()
    # the block's layer, point file and counts are still the first store's
    assert Block(blk).info()["mass_points_count"] == "1000"
    assert len(Block(blk).points()) == 1000 == layer_rows(blk)
    leftovers = sorted(f.name for f in tmp_path.glob("b.mass_points.*"))
    assert len(leftovers) == 2  # the killed store's folder, not referenced
    # the next store removes what the killed one left and switches to its own points
    Block(blk).store_points(two_ray_points(7), display=(FlatModel(), 1, 0.0), replace_fewer=True)
    assert not any(t.startswith("mass_points__staged_") for t in tables(blk))
    assert [f.name for f in tmp_path.glob("b.mass_points.*")] == [Block(blk).info()["mass_points"]]
    assert len(Block(blk).points()) == 7 == layer_rows(blk)


def test_a_store_waits_for_another_writer_then_says_so(blk, monkeypatch):
    monkeypatch.setattr(schema, "BUSY_TIMEOUT_MS", 300)
    holder = sqlite3.connect(blk, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")
    try:
        with pytest.raises(StorageError, match="program.* keeps it locked .* nothing was stored"):
            Block(blk).store_points(two_ray_points(5), display=(FlatModel(), 1, 0.0), replace_fewer=True)
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert len(Block(blk).points()) == 1000 == layer_rows(blk)


def test_generations_count_every_change(small_scene_block, tmp_path):
    path = str(tmp_path / "g.gpkg")
    shutil.copy(small_scene_block[0], path)
    start = Block(path).generations()
    cp.import_csv(Block(path), write_csv(small_scene_block[1], tmp_path), suffix="_meas")
    after_import = Block(path).generations()
    assert after_import["control_points"] > start["control_points"]
    assert after_import["models"] == start["models"] and after_import["mass_points"] == start["mass_points"]
    ds = ogr.Open(path, 1)  # an edit in QGIS's attribute table, through OGR
    ds.ExecuteSQL("UPDATE control_points SET h = h + 1 WHERE name = 'P001'")
    ds = None
    assert Block(path).generations()["control_points"] > after_import["control_points"]
    edited = Block(path).generations()
    ds = ogr.Open(path, 1)  # the adjustment's residual field is not a change of the set
    ds.GetLayerByName("control_points").CreateField(ogr.FieldDefn("residual_px", ogr.OFTReal))
    ds.ExecuteSQL("UPDATE control_points SET residual_px = 0.5")
    ds = None
    assert Block(path).generations() == edited
    models = {r["id"]: Block(path).model(r["id"]) for r in Block(path).images()}
    Block(path).save_models(models)
    assert Block(path).generations()["models"] == edited["models"] + 1


def write_csv(rows, folder):
    path = folder / "points.csv"
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return str(path)
