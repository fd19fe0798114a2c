"""QGIS Georeferencer .points files (measurement/georeferencer.py): the file written for one image
(QGIS 3.22 layout, UTM map coordinates against OSR point by point, pixelY = -row), read back as
2-D reference points (XY from the map, Z from the DTM or a height), and the reader's errors."""

import shutil

import numpy as np
import pytest
from osgeo import osr

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.geodesy import utm_epsg
from pushbroom.algorithms.measurement.georeferencer import HEADER, read_points, write_points
from tests.helpers.osr_oracle import utm

HRG = 1


@pytest.fixture
def observations(small_scene, small_scene_block, tmp_path):
    """The simulator's points and measurements as stored in a copy of the small scene's block."""
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    return cp.import_csv(Block(path), small_scene["points"], suffix="_meas", check_ids=["P002"])


def test_write_and_read_back(observations, small_scene, tmp_path, figures):
    obs = observations
    path = write_points(tmp_path / "hrg.points", obs, HRG)
    lines = open(path).read().splitlines()
    epsg = utm_epsg(obs.points["lon"].mean(), obs.points["lat"].mean())
    assert lines[0].startswith("#CRS: ") and lines[1] == HEADER and len(lines) == 2 + len(obs.points)
    stated = osr.SpatialReference()
    stated.SetFromUserInput(lines[0][len("#CRS: ") :])
    expected = osr.SpatialReference()
    expected.ImportFromEPSG(epsg)
    assert stated.IsSame(expected)
    rows = np.array([[float(v) for v in line.split(",")] for line in lines[2:]])
    m = obs.measurements[obs.measurements["image_id"] == HRG]
    x, y = utm(obs.points["lon"][m["point"]], obs.points["lat"][m["point"]], epsg)
    assert np.abs(rows[:, 0] - x).max() < 1e-6 and np.abs(rows[:, 1] - y).max() < 1e-6
    assert rows[:, 2].tolist() == m["col"].tolist() and rows[:, 3].tolist() == (-m["row"]).tolist()
    assert (rows[:, 4:] == [1, 0, 0, 0]).all()
    # back as reference points: Z from the true DTM
    dtm = read_dem(small_scene["dtm"])
    back = read_points(path, HRG, dem=dtm, role="check", prefix="G")
    assert back.points["name"].tolist() == [f"G{k}" for k in range(1, len(m) + 1)]
    assert (back.points["role"] == "check").all()
    assert np.abs(back.points["lon"] - obs.points["lon"]).max() < 1e-9
    assert np.abs(back.points["lat"] - obs.points["lat"]).max() < 1e-9
    assert np.abs(back.points["h"] - obs.points["h"]).max() < 0.05  # the simulator's sites lie on its DTM
    assert back.points[["sigma_e", "sigma_n", "sigma_h"]].tolist() == [cp.DEFAULT_SIGMAS] * len(m)
    bm = back.measurements
    assert bm["col"].tolist() == m["col"].tolist() and bm["row"].tolist() == m["row"].tolist()
    assert (bm["image_id"] == HRG).all() and (bm["sigma"] == 0.5).all()
    # a given height, the map CRS given explicitly
    flat = read_points(path, HRG, height=250.0, crs=f"EPSG:{epsg}")
    assert (flat.points["h"] == 250.0).all() and (flat.points["role"] == "control").all()
    figures.report("points through the Georeferencer file", len(m))
    figures.report("largest lon difference read back", np.abs(back.points["lon"] - obs.points["lon"]).max(), "deg")


def write(path, text):
    path.write_text(text)
    return str(path)


def test_reader_conventions_and_errors(tmp_path):
    body = "500000,4000000,10.5,-20.25,1,0,0,0\n500100,4000100,30,-40,0,0.1,0.2,0.22\n500200,4000200,50,-60\n"
    plain = write(tmp_path / "plain.points", HEADER + "\n" + body)
    with pytest.raises(InputError, match="no '#CRS:' line"):
        read_points(plain, 2, height=100.0)
    obs = read_points(plain, 2, height=100.0, crs="EPSG:32616")
    assert obs.points["name"].tolist() == ["GEO1", "GEO3"]  # the disabled row is skipped
    assert obs.measurements["col"].tolist() == [10.5, 50.0] and obs.measurements["row"].tolist() == [20.25, 60.0]
    x, y = utm(obs.points["lon"], obs.points["lat"], 32616)
    assert np.abs(x - [500000, 500200]).max() < 1e-6 and np.abs(y - [4000000, 4000200]).max() < 1e-6
    # column/line of a georeferenced source (pixelY positive), tab-separated older files
    lines = write(tmp_path / "lines.points", "mapX\tmapY\tpixelX\tpixelY\tenable\n500000\t4000000\t10\t20\t1\n")
    assert read_points(lines, 2, height=0.0, crs=32616).measurements["row"].tolist() == [20.0]
    # the file's CRS wins; a different one given is an error
    wkt = osr.SpatialReference()
    wkt.ImportFromEPSG(32616)
    stated = write(tmp_path / "stated.points", f"#CRS: {wkt.ExportToWkt()}\n{HEADER}\n{body}")
    assert read_points(stated, 2, height=0.0).points["lon"].tolist() == obs.points["lon"].tolist()
    with pytest.raises(InputError, match="states its CRS as"):
        read_points(stated, 2, height=0.0, crs="EPSG:32617")
    # a DEM without heights there falls back to the height, else names the line
    nowhere = Dem.constant(300.0, (10.0, 10.0, 10.1, 10.1))
    assert (read_points(plain, 2, dem=nowhere, height=7.0, crs=32616).points["h"] == 7.0).all()
    with pytest.raises(InputError, match="line 2: the DEM has no height"):
        read_points(plain, 2, dem=nowhere, crs=32616)
    with pytest.raises(InputError, match="give a DEM or a height"):
        read_points(plain, 2, crs=32616)
    bad = [
        ("x.points", f"{HEADER}\n500000,4000000,1\n", "line 2: 3 field"),
        ("y.points", f"{HEADER}\n500000,4000000,1,-2,1\n5000a0,4000000,1,-2,1\n", "line 3: .* is not numbers"),
        ("z.points", "500000,4000000,1,-2,1\n", "line 1: expected the header"),
        ("m.points", f"{HEADER}\n500000,4000000,1,-2\n500000,4000000,1,2\n", "line 3: pixelY 2.0 is positive"),
        ("e.points", f"{HEADER}\n500000,4000000,1,-2,0\n", "no enabled point"),
        ("n.points", f"{HEADER}\n500000,4000000,1,nan\n", "line 2: coordinates must be finite"),
    ]
    for name, text, message in bad:
        with pytest.raises(InputError, match=message):
            read_points(write(tmp_path / name, text), 2, height=0.0, crs=32616)
    with pytest.raises(InputError, match="role must be one of"):
        read_points(plain, 2, height=0.0, crs=32616, role="tie")


def test_write_refuses_an_image_without_measurements(observations, tmp_path):
    obs = observations.subset(np.ones(len(observations.points), bool))
    obs.measurements = obs.measurements[obs.measurements["image_id"] != 3]
    with pytest.raises(InputError, match="no point is measured in image 3"):
        write_points(tmp_path / "none.points", obs, 3)
    assert not (tmp_path / "none.points").exists()
