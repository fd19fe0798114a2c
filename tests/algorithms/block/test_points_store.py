"""MultiPoints storage beside a block, the point layer, and tie point selection."""

import os

import numpy as np
import pytest
from osgeo import ogr

from pushbroom.algorithms.block import Block, points as points_store
from pushbroom.algorithms.block.points import load_arrays, save_arrays
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.errors import InputError, StorageError
from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.matching.tiepoints import select_tie_points
from tests.helpers.feedback import Feedback
from tests.helpers.points_synthetic import FlatModel, synthetic


@pytest.fixture
def block(tmp_path):
    path = tmp_path / "b.gpkg"
    create_schema(path)
    return path


def assert_same(a, b):
    assert a.points.dtype == b.points.dtype and a.points.tobytes() == b.points.tobytes()
    assert a.observations.dtype == b.observations.dtype and a.observations.tobytes() == b.observations.tobytes()
    assert a.stats == b.stats


def test_save_and_load_beside_the_block(block, tmp_path):
    mp = synthetic(3000)
    path = Block(block).store_points(mp)
    info = Block(block).info()
    assert info["mass_points"] == os.path.basename(path) and info["mass_points_count"] == "3000"
    assert os.path.basename(path).startswith("b.mass_points.") and os.path.isdir(path)
    assert_same(Block(block).points(), mp)
    # saving again replaces (no duplicate keys, the old file removed; far fewer points only when asked),
    # other kinds are separate
    Block(block).store_points(mp.subset([1, 2, 3]), replace_fewer=True)
    Block(block).store_points(mp.subset([5]), kind="tie_points")
    assert len(Block(block).points()) == 3 and len(Block(block).points("tie_points")) == 1
    assert Block(block).info()["mass_points_count"] == "3"
    assert sorted(f.name.split(".")[1] for f in tmp_path.glob("b.*_points.*")) == ["mass_points", "tie_points"]
    assert [f for f in tmp_path.iterdir() if ".part" in f.name] == []


def test_a_copy_of_the_block_never_removes_the_points_of_the_original(block, tmp_path):
    """A copied block file references the original's point folder: storing points into the copy leaves it."""
    import shutil

    mp = synthetic(3000)
    original = Block(block).store_points(mp)
    copy = tmp_path / "copy.gpkg"
    shutil.copyfile(block, copy)
    assert_same(Block(copy).points(), mp)  # the copy reads the original's points
    mine = Block(copy).store_points(mp.subset(list(range(1, 2001))))
    assert os.path.isdir(original) and os.path.basename(mine).startswith("copy.mass_points.")
    assert_same(Block(block).points(), mp)
    assert len(Block(copy).points()) == 2000


def test_two_million_points_round_trip(tmp_path):
    mp = synthetic(2_000_000)
    path = save_arrays(tmp_path / "big.npz", mp)
    assert_same(load_arrays(path), mp)


def test_parts_hold_the_points_in_id_order(block, tmp_path, monkeypatch):
    monkeypatch.setattr(points_store, "PART_POINTS", 1000)
    mp = synthetic(3500)
    shuffled = MultiPoints(mp.points[::-1], mp.observations[::-1], mp.stats)
    Block(block).store_points(shuffled)
    parts = Block(block).point_parts()
    assert [os.path.basename(p) for p in parts] == [f"part-{k:05d}.npz" for k in range(4)]
    loaded = [load_arrays(p) for p in parts]
    assert [len(p) for p in loaded] == [1000, 1000, 1000, 500]
    # each part holds its points' observations and no other
    for part in loaded:
        assert set(part.observations["point_id"]) == set(part.points["id"])
    assert_same(Block(block).points(), mp)
    index = points_store.read_index(os.path.dirname(parts[0]))
    assert [(p["first_id"], p["last_id"]) for p in index["parts"]] == [
        (1, 1000),
        (1001, 2000),
        (2001, 3000),
        (3001, 3500),
    ]


def test_a_point_file_of_earlier_versions_is_read_as_one_part(block, tmp_path):
    mp = synthetic(50)
    path = save_arrays(tmp_path / "b.mass_points.npz", mp)
    Block(block).update_info({"mass_points": "b.mass_points.npz"})
    assert Block(block).point_parts() == [str(path)]
    assert_same(Block(block).points(), mp)


def test_missing_points_give_clear_errors(block, tmp_path):
    with pytest.raises(InputError, match="matchpoints"):
        Block(block).points()
    with pytest.raises(InputError, match="missing"):
        load_arrays(tmp_path / "nothing.npz")
    with pytest.raises(InputError, match="no block"):
        Block(tmp_path / "none.gpkg").store_points(synthetic(3))
    (tmp_path / "x.npz").write_bytes(b"not a zip")
    with pytest.raises(StorageError, match="x.npz is damaged"):
        load_arrays(tmp_path / "x.npz")
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "index.json").write_text('{"format": "pushbroom-multipoints-parts-1", "par')
    with pytest.raises(StorageError, match="folder is damaged"):
        load_arrays(tmp_path / "folder")


def test_point_layer(block):
    mp = synthetic(300)
    source = Block(block).write_point_layer("mass_points", mp, FlatModel(), 1, 500.0)
    assert source.endswith("|layername=mass_points")
    Block(block).write_point_layer("mass_points", mp, FlatModel(), 3, 500.0)  # replaced, image 3 lacks group 1
    ds = ogr.Open(str(block))
    layer = ds.GetLayerByName("mass_points")
    assert layer.GetFeatureCount() == 200
    assert layer.GetSpatialRef().GetAuthorityCode(None) == "4326"
    feat = layer.GetNextFeature()
    pid = feat["id"]
    col, row = mp.coordinates(3)
    geom = feat.GetGeometryRef()
    assert geom.GetX() == pytest.approx(-84.2 + col[pid - 1] * 1e-5)
    assert geom.GetY() == pytest.approx(36.6 - row[pid - 1] * 1e-5)
    assert feat["group"] == mp.points["group"][pid - 1]
    assert feat["rho"] == pytest.approx(float(mp.points["rho_min"][pid - 1]))


def test_tie_points_one_per_cell_best_group_then_rho():
    p = np.zeros(6, POINT_DTYPE)
    p["id"] = np.arange(1, 7)
    p["group"] = [1, 3, 3, 2, 1, 1]
    p["rho_min"] = [0.99, 0.7, 0.8, 0.95, 0.9, 0.7]
    obs = np.zeros(6, OBS_DTYPE)
    obs["point_id"], obs["image_id"] = p["id"], 4
    # cell (0, 0): points 1-3 -> best group 3, highest rho: point 3; cell (1, 0): 4, 5 -> 4 (group 2)
    # cell (0, 1): 6 alone
    obs["col"] = [10, 50, 99.9, 150, 199, 10]
    obs["row"] = [10, 20, 30, 10, 90, 100]
    mp = MultiPoints(p, obs, {"images": [4]})
    tie = select_tie_points(mp, cell=100)
    assert tie.points["id"].tolist() == [3, 4, 6]
    assert tie.stats["tie_cell"] == 100
    assert select_tie_points(mp, cell=1000).points["id"].tolist() == [3]
    assert select_tie_points(mp, cell=100, min_group=2).points["id"].tolist() == [3, 4]
    with pytest.raises(InputError):
        select_tie_points(mp, cell=0)
    assert len(select_tie_points(MultiPoints())) == 0


def test_tie_points_keep_observations_and_ids():
    mp = synthetic(5000)
    tie = select_tie_points(mp, cell=100)
    assert 90 <= len(tie) <= 100  # 10 x 10 cells, all occupied
    assert np.all(tie.points["group"] == 3)  # group 3 exists in every cell
    col, row = tie.coordinates(1)
    cells = np.floor(row / 100) * 10 + np.floor(col / 100)
    assert len(np.unique(cells)) == len(tie)
    # each selected point is the best group-3 point of its cell
    all_col, all_row = mp.coordinates(1)
    all_cells = np.floor(all_row / 100) * 10 + np.floor(all_col / 100)
    for pid, cell in zip(tie.points["id"], cells):
        rivals = (all_cells == cell) & (mp.points["group"] == 3)
        assert mp.points["rho_min"][pid - 1] == mp.points["rho_min"][rivals].max()
    assert np.array_equal(np.unique(tie.observations["point_id"]), tie.points["id"])
    assert len(tie.observations) == 3 * len(tie)


def test_a_large_point_set_is_shown_by_a_uniform_subsample(block, monkeypatch):
    """Above DISPLAY_POINTS the layer shows about that many points, spread evenly over the ids (so over a
    tile-ordered dense lattice) and over the image; the stored points are all kept."""
    monkeypatch.setattr(points_store, "PART_POINTS", 3000)
    monkeypatch.setattr(points_store, "DISPLAY_POINTS", 2500)
    mp = synthetic(10_000)
    log = Feedback()
    Block(block).store_points(mp, display=(FlatModel(), 1, 500.0), feedback=log)
    assert len(Block(block).points()) == 10_000
    ds = ogr.Open(str(block))
    ids = np.array([f["id"] for f in ds.GetLayerByName("mass_points")])
    ds = None
    seen = mp.points["id"][np.isin(mp.points["id"], mp.observations["point_id"][mp.observations["image_id"] == 1])]
    assert len(ids) == pytest.approx(0.25 * len(seen), rel=0.02)
    assert np.isin(ids, seen).all()
    counts = np.histogram(ids, bins=10, range=(1, 10_001))[0]
    expected = 0.25 * np.histogram(seen, bins=10, range=(1, 10_001))[0]
    assert np.all(np.abs(counts - expected) < 0.1 * expected)
    assert any("shows a uniform 25.0 % of the 10000 points" in m for m in log.messages)
