"""Control/check point CSV import and export and their storage in the block GeoPackage."""

import csv
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.geodesy import utm_epsg
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from tests.helpers.feedback import Feedback
from tests.helpers.osr_oracle import utm

NAMES = ("HRG", "HRS1", "HRS2")


@pytest.fixture
def scene(small_scene, small_scene_block):
    """The simulated triplet, its points.csv rows and an empty block of its three images."""
    return {"paths": small_scene, "rows": small_scene_block[1], "block": small_scene_block[0]}


@pytest.fixture
def blk(scene, tmp_path):
    path = tmp_path / "block.gpkg"
    shutil.copy(scene["block"], path)
    return str(path)


def write_rows(path, rows, header=None):
    header = header or list(rows[0])
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, header, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    return str(path)


def blanked(rows):
    """A copy of the simulator rows with a few measurements left empty (not measured there)."""
    rows = [dict(r) for r in rows]
    for k, name in [(1, "HRS2"), (2, "HRG"), (2, "HRS1")]:
        rows[k][f"{name}_col_meas"] = rows[k][f"{name}_row_meas"] = ""
    return rows


def same(a, b):
    return a.points.tobytes() == b.points.tobytes() and a.measurements.tobytes() == b.measurements.tobytes()


def test_simulator_points_import(scene, blk, tmp_path):
    rows = blanked(scene["rows"])
    path = write_rows(tmp_path / "points.csv", rows)
    ids = Block(blk).image_ids()
    log = Feedback()
    obs = cp.import_csv(Block(blk), path, suffix="_meas", feedback=log)
    assert any("ignored column" in m and "HRG_blunder" in m and "HRS1_col," in m for m in log.messages)
    cells = [
        (k, ids[n], float(r[f"{n}_col_meas"]), float(r[f"{n}_row_meas"]))
        for k, r in enumerate(rows)
        for n in NAMES
        if r[f"{n}_col_meas"]
    ]
    assert len(obs.points) == len(rows) >= 5
    assert len(obs.measurements) == len(cells) == 3 * len(rows) - 3
    assert obs.points["name"].tolist() == [r["id"] for r in rows]
    assert (obs.points["role"] == "control").all()
    for key in ("lon", "lat", "h"):
        assert obs.points[key].tolist() == [float(r[key]) for r in rows]
    assert obs.points[["sigma_e", "sigma_n", "sigma_h"]].tolist() == [cp.DEFAULT_SIGMAS] * len(rows)
    m = obs.measurements
    assert sorted(zip(m["point"].tolist(), m["image_id"].tolist(), m["col"].tolist(), m["row"].tolist())) == cells
    assert (m["sigma"] == IMAGE_SIGMA).all()
    assert same(Block(blk).control_points(), obs)
    # the stored layer and table, read with OGR
    ds = ogr.Open(blk)
    layer = ds.GetLayerByName("control_points")
    assert layer.GetSpatialRef().GetAuthorityCode(None) == "4326" and layer.GetGeomType() == ogr.wkbPoint25D
    xyz = [feat.GetGeometryRef().GetPoint() for feat in layer]
    assert xyz == [(float(r["lon"]), float(r["lat"]), float(r["h"])) for r in rows]
    assert ds.GetLayerByName("image_measurements").GetFeatureCount() == len(cells)
    log_rows = [(f["step"], f["message"]) for f in ds.GetLayerByName("run_log")]
    assert log_rows[-1][0] == "importpoints" and f"control {len(rows)}, check 0" in log_rows[-1][1]
    info = Block(blk).info()
    assert info["control_points"] == str(len(rows)) and info["image_measurements"] == str(len(cells))


def test_roles_and_check_ids(scene, blk, tmp_path):
    rows = [dict(r, role="check" if k == 0 else "") for k, r in enumerate(scene["rows"])]
    path = write_rows(tmp_path / "roles.csv", rows)
    ids = Block(blk).image_ids()
    obs = cp.read_csv(path, ids, cp.CsvOptions(suffix="_meas", check_ids=["P003"]))
    assert obs.points["role"].tolist() == ["check", "control", "check"] + ["control"] * (len(rows) - 3)
    obs = cp.read_csv(path, ids, cp.CsvOptions(suffix="_meas", default_role="check"))
    assert (obs.points["role"] == "check").all()
    with pytest.raises(InputError, match="P999"):
        cp.read_csv(path, ids, cp.CsvOptions(suffix="_meas", check_ids=["P001", "P999"]))
    text = cp.summary(cp.read_csv(path, ids, cp.CsvOptions(suffix="_meas", check_ids=["P002"])), ids)
    assert text.startswith(f"control {len(rows) - 2}, check 2; HRG: {len(rows) - 2} control, 2 check;")


def test_projected_input(scene, blk, tmp_path, figures):
    """x/y in UTM made with osr from known lon/lat come back to 1e-8 deg, with the CRS as EPSG code or WKT."""
    rows = scene["rows"]
    lon, lat = np.array([float(r["lon"]) for r in rows]), np.array([float(r["lat"]) for r in rows])
    epsg = utm_epsg(lon.mean(), lat.mean())
    xy = utm(lon, lat, epsg).T
    assert 1e5 < xy[:, 0].min() and xy[:, 1].min() > 4e6  # really projected metres
    projected = [
        {
            "ID": r["id"],
            "X": repr(x),
            "Y": repr(y),
            "H": r["h"],
            "HRG_col": r["HRG_col_meas"],
            "HRG_row": r["HRG_row_meas"],
        }
        for r, (x, y) in zip(rows, xy)
    ]
    path = write_rows(tmp_path / "utm.csv", projected)
    wkt = osr.SpatialReference()
    wkt.ImportFromEPSG(epsg)
    for crs in (f"EPSG:{epsg}", wkt.ExportToWkt(), epsg):
        obs = cp.read_csv(path, Block(blk).image_ids(), cp.CsvOptions(crs=crs))
        err = max(np.abs(obs.points["lon"] - lon).max(), np.abs(obs.points["lat"] - lat).max())
        assert err < 1e-8, err
    figures.report(f"UTM {epsg} -> WGS 84, largest difference", err, "deg")
    with pytest.raises(InputError, match="swapped|projected"):
        cp.read_csv(path, Block(blk).image_ids())  # metres read as degrees
    with pytest.raises(InputError, match="unknown coordinate reference system"):
        cp.read_csv(path, Block(blk).image_ids(), cp.CsvOptions(crs="EPSG:999999"))


def egm96_grid():
    for folder in osr.GetPROJSearchPaths() or []:
        for name in ("us_nga_egm96_15.tif", "egm96_15.gtx"):
            if os.path.exists(os.path.join(folder, name)):
                return os.path.join(folder, name)
    pytest.skip("PROJ's EGM96 grid (us_nga_egm96_15.tif / egm96_15.gtx) is not installed")


def test_orthometric_heights_add_the_egm96_undulation(scene, blk, tmp_path, figures):
    """h - H equals the EGM96 grid read by GDAL and interpolated bilinearly (to 1 mm)."""
    grid = gdal.Open(egm96_grid())
    gt, undulation = grid.GetGeoTransform(), grid.ReadAsArray().astype(float)
    rows = scene["rows"]
    path = write_rows(tmp_path / "ortho.csv", rows)
    ell = cp.read_csv(path, Block(blk).image_ids(), cp.CsvOptions(suffix="_meas"))
    ortho = cp.read_csv(path, Block(blk).image_ids(), cp.CsvOptions(suffix="_meas", heights="orthometric"))
    assert ortho.points[["lon", "lat"]].tolist() == ell.points[["lon", "lat"]].tolist()
    lon, lat = ell.points["lon"], ell.points["lat"]
    x, y = (np.mod(lon - gt[0], 360.0)) / gt[1] - 0.5, (lat - gt[3]) / gt[5] - 0.5
    j, i = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - j, y - i
    n = (1 - fy) * ((1 - fx) * undulation[i, j] + fx * undulation[i, j + 1]) + fy * (
        (1 - fx) * undulation[i + 1, j] + fx * undulation[i + 1, j + 1]
    )
    diff = ortho.points["h"] - ell.points["h"]
    assert np.abs(diff - n).max() < 1e-3, (diff, n)
    figures.report("EGM96 undulation at the scene, h - H", diff.mean(), "m", f"grid {n.mean():.3f} m")


def test_missing_geoid_grid_is_a_clear_error(tmp_path):
    """Without the grid (PROJ data folder holding only proj.db) orthometric heights are refused."""
    proj_db = next(
        (
            os.path.join(f, "proj.db")
            for f in osr.GetPROJSearchPaths() or []
            if os.path.exists(os.path.join(f, "proj.db"))
        ),
        None,
    )
    if proj_db is None:
        pytest.skip("proj.db not found")
    data = tmp_path / "proj"
    data.mkdir()
    shutil.copy(proj_db, data)
    code = (
        "from pushbroom.algorithms.adjustment.control_points import orthometric_to_ellipsoidal\n"
        "from pushbroom.algorithms.errors import InputError\n"
        "import sys\n"
        "try:\n    sys.stdout.write(repr(orthometric_to_ellipsoidal(-84.2, 36.6, 300.0)))\n"
        "except InputError as exc:\n    sys.stdout.write(f'InputError: {exc}')\n"
    )
    env = dict(
        os.environ,
        PROJ_DATA=str(data),
        PROJ_LIB=str(data),
        PROJ_NETWORK="OFF",
        HOME=str(tmp_path),
        XDG_DATA_HOME=str(tmp_path),
    )
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.stdout.startswith("InputError:"), out.stdout + out.stderr
    assert "EGM96 geoid grid" in out.stdout and "us_nga_egm96_15.tif" in out.stdout


def test_export_import_round_trip(scene, blk, tmp_path):
    cp.import_csv(
        Block(blk), write_rows(tmp_path / "points.csv", blanked(scene["rows"])), suffix="_meas", check_ids=["P002"]
    )
    stored = Block(blk).control_points()
    out = tmp_path / "export.csv"
    assert same(cp.export_csv(Block(blk), out), stored)
    ids = Block(blk).image_ids()
    again = cp.read_csv(out, ids)
    assert same(again, stored)
    cp.write_csv(tmp_path / "again.csv", again, ids)
    assert (tmp_path / "again.csv").read_text() == out.read_text()
    # arbitrary doubles (full precision, tiny and large) survive too
    rng = np.random.default_rng(3)
    points = np.zeros(20, POINT_DTYPE)
    points["name"] = [f"Q{k}" for k in range(20)]
    points["role"] = np.where(rng.random(20) < 0.3, "check", "control")
    points["lon"], points["lat"] = rng.uniform(-180, 180, 20), rng.uniform(-90, 90, 20)
    points["h"] = rng.uniform(-400, 9000, 20) * 10.0 ** rng.integers(-8, 2, 20)
    for key in ("sigma_e", "sigma_n", "sigma_h"):
        points[key] = rng.uniform(1e-4, 30, 20)
    meas = np.zeros(45, MEAS_DTYPE)
    pairs = sorted(rng.choice(60, 45, replace=False))
    meas["point"], meas["image_id"] = np.divmod(pairs, 3)
    meas["image_id"] = np.array(list(ids.values()))[meas["image_id"]]
    meas["col"], meas["row"], meas["sigma"] = rng.uniform(0, 1e4, 45), rng.uniform(0, 1e4, 45), rng.uniform(0.01, 3, 45)
    synthetic = Observations(points, meas)
    cp.write_csv(tmp_path / "synthetic.csv", synthetic, ids)
    assert same(cp.read_csv(tmp_path / "synthetic.csv", ids), synthetic)


def test_merge_updates_and_replace_replaces(scene, blk, tmp_path):
    rows = scene["rows"]
    ids = Block(blk).image_ids()
    cp.import_csv(Block(blk), write_rows(tmp_path / "first.csv", rows[:4]), suffix="_meas")
    before = Block(blk).control_points()
    update = [
        dict(
            rows[2],
            h="1000.5",
            HRG_col_meas="10.25",
            HRG_row_meas="20.5",
            HRS1_col_meas="",
            HRS1_row_meas="",
            HRS2_col_meas="",
            HRS2_row_meas="",
            role="check",
        ),
        dict(rows[5], id="NEW", role=""),
    ]
    # P003's made-up HRG measurement lies 1 km from where its coordinates project: kept (this is about merging)
    merged = cp.import_csv(
        Block(blk),
        write_rows(tmp_path / "update.csv", update, list(rows[0]) + ["role"]),
        suffix="_meas",
        mode="merge",
        keep_implausible=True,
    )
    assert same(Block(blk).control_points(), merged)
    assert merged.points["name"].tolist() == ["P001", "P002", "P003", "P004", "NEW"]
    keep = [0, 1, 3]
    assert merged.points[keep].tobytes() == before.points[keep].tobytes()
    assert merged.points[2][["role", "h"]].tolist() == ("check", 1000.5)
    m = merged.measurements
    p3 = m[m["point"] == 2]
    assert p3[["image_id", "col", "row"]].tolist()[0] == (ids["HRG"], 10.25, 20.5)
    old3 = before.measurements[before.measurements["point"] == 2]
    assert p3[1:].tobytes() == old3[1:].tobytes()  # HRS1, HRS2 kept
    assert (m["point"] == 4).sum() == 3 and len(m) == len(before.measurements) + 3
    # 2 points for 5: far fewer, replaced only when asked (block/replacement.py)
    replaced = cp.import_csv(
        Block(blk), tmp_path / "update.csv", suffix="_meas", replace_fewer=True, keep_implausible=True
    )
    assert replaced.points["name"].tolist() == ["P003", "NEW"] and len(replaced.measurements) == 4
    assert same(Block(blk).control_points(), replaced)


BAD = [
    ("missing column", lambda r: [{k: v for k, v in x.items() if k != "h"} for x in r], "no column 'h'"),
    (
        "unknown image",
        lambda r: [dict(x, SPOT4_col_meas="1", SPOT4_row_meas="2") for x in r],
        "SPOT4_col_meas, SPOT4_row_meas name images that are not in the block; the block's images are HRG, HRS1, HRS2",
    ),
    (
        "not a number",
        lambda r: [dict(x, lat="36.6x" if k == 1 else x["lat"]) for k, x in enumerate(r)],
        r"line 3, column lat: '36.6x' is not a finite number",
    ),
    (
        "bad measurement",
        lambda r: [dict(x, HRS1_row_meas="nan" if k == 3 else x["HRS1_row_meas"]) for k, x in enumerate(r)],
        r"line 5, column HRS1_row_meas: 'nan'",
    ),
    (
        "duplicate id",
        lambda r: [dict(x, id="P001" if k == 2 else x["id"]) for k, x in enumerate(r)],
        "line 4: point id 'P001' is used again \\(first on line 2\\)",
    ),
    (
        "half a measurement",
        lambda r: [dict(x, HRG_row_meas="" if k == 0 else x["HRG_row_meas"]) for k, x in enumerate(r)],
        "line 2, column HRG_row_meas: empty",
    ),
    (
        "outside the image",
        lambda r: [dict(x, HRG_col_meas="1e5" if k == 0 else x["HRG_col_meas"]) for k, x in enumerate(r)],
        "outside image HRG",
    ),
    ("bad role", lambda r: [dict(x, role="gcp") for x in r], "line 2, column role: role 'gcp'"),
    ("bad sigma", lambda r: [dict(x, sigma_h="-1") for x in r], "line 2, column sigma_h: '-1' is not a positive"),
]


@pytest.mark.parametrize("case, edit, message", BAD, ids=[b[0] for b in BAD])
def test_bad_file_leaves_the_block_unchanged(scene, blk, tmp_path, case, edit, message):
    cp.import_csv(Block(blk), write_rows(tmp_path / "good.csv", scene["rows"]), suffix="_meas", check_ids=["P004"])
    before = Block(blk).control_points()
    rows = edit(scene["rows"])
    bad = write_rows(tmp_path / "bad.csv", rows, list(rows[0]))
    for mode in Block.IMPORT_MODES:
        with pytest.raises(InputError, match=message):
            cp.import_csv(Block(blk), bad, suffix="_meas", mode=mode)
        assert same(Block(blk).control_points(), before)


def test_cancelled_save_rolls_back(scene, blk, tmp_path):
    path = write_rows(tmp_path / "points.csv", scene["rows"])
    ids = Block(blk).image_ids()
    obs = cp.read_csv(path, ids, cp.CsvOptions(suffix="_meas"))
    with pytest.raises(CancelledError):  # the first import: nothing lands
        Block(blk).save_control_points(obs, feedback=Feedback(cancel_after=3))
    assert len(Block(blk).control_points().points) == 0
    ds = ogr.Open(blk)
    log_rows = ds.GetLayerByName("run_log").GetFeatureCount()
    ds = None
    Block(blk).save_control_points(obs.subset(np.arange(len(obs.points)) < 3))
    before = Block(blk).control_points()
    for mode in Block.IMPORT_MODES:
        with pytest.raises(CancelledError):
            Block(blk).save_control_points(obs, mode=mode, feedback=Feedback(cancel_after=len(obs.points) - 1))
        assert same(Block(blk).control_points(), before)
    ds = ogr.Open(blk)
    assert ds.GetLayerByName("run_log").GetFeatureCount() == log_rows + 1
    assert ds.GetLayerByName("control_points").GetFeatureCount() == 3


def test_delimiters_aliases_and_case(blk, tmp_path):
    ids = Block(blk).image_ids()
    text = (
        "\ufeffName;LON;Lat;Height;Sigma_H;hrg_COL;HRG_Row;HRG_sigma;HRS2_col;HRS2_row\n"
        "A;-84.2;36.6;300.5;0.75;10.5;20.5;0.25;;\n\n"
        "B;-84.19;36.61;310;;11;21;;30.5;40.5\n"
    )
    path = tmp_path / "semicolon.csv"
    path.write_text(text, encoding="utf-8")
    obs = cp.read_csv(path, ids)
    assert obs.points[["name", "lon", "lat", "h", "sigma_h"]].tolist() == [
        ("A", -84.2, 36.6, 300.5, 0.75),
        ("B", -84.19, 36.61, 310.0, 2.2),
    ]
    assert obs.measurements.tolist() == [
        (0, ids["HRG"], 10.5, 20.5, 0.25),
        (1, ids["HRG"], 11.0, 21.0, 0.5),
        (1, ids["HRS2"], 30.5, 40.5, 0.5),
    ]
    extra = tmp_path / "extra.csv"
    extra.write_text("id,lon,lat,h\nA,-84.2,36.6,300\nB,-84.2,36.6,300,7\n")
    with pytest.raises(InputError, match="line 3: 5 fields, the header has 4"):
        cp.read_csv(extra, ids)
