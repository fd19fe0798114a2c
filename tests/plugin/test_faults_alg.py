"""Faults a user meets, through qgis_process as the user ran them (issue 19's trials): a full disk, a folder
that cannot be written, an unknown CRS, a foreign or damaged file, a block locked or changed by another
program. Each ends with exit status 1 and ONE clear message (no traceback, not printed three times), and
leaves nothing half-written under a final name and the block as it was."""

import os
import shutil
import sqlite3
import subprocess

import numpy as np
import pytest
from osgeo import ogr
from qgis import processing
from qgis.core import QgsProcessingException

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.crs import reproject, srs, wgs84
from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.surface.pointcloud import write_point_cloud
from tests.helpers.other_user import USER, as_other_user, public_folder
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env


@pytest.fixture(scope="module")
def public():
    """A folder every user may enter and read: where the runs made as another user find their profile and
    inputs."""
    with public_folder("pushbroom-faults-") as folder:
        yield folder


@pytest.fixture(scope="module")
def runner(public):
    """Run qgis_process (`run(*args, user=None)` -> CompletedProcess) with a profile that has the plugin;
    `user="other"` runs it as an unprivileged user where the tests run as root (root may write anywhere)."""
    world = public / "world"  # a profile and a home the other user can write
    env = dict(qgis_process_env(world / "profile"), HOME=str(world))
    if os.geteuid() == 0:
        subprocess.run(["chown", "-R", USER, str(world)], check=True)

    def run(*args, user=None):
        command, run_env = [QGIS_PROCESS, "run", *args], env
        if user == "other":
            command, run_env = as_other_user(command, public, env)
        return subprocess.run(command, env=run_env, capture_output=True, text=True, timeout=600)

    return run


def failed_once(result, fragment):
    """The run failed with `fragment` in its error, printed once and without a traceback."""
    assert result.returncode == 1, result.stdout[-2000:] + result.stderr[-2000:]
    assert result.stderr.count(fragment) == 1, result.stderr
    assert "Traceback" not in result.stderr and "ERROR:\t" in result.stderr
    return result.stderr


@pytest.fixture
def tiny_disk(tmp_path):
    folder = tmp_path / "tiny"
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=3m,mode=1777", "tmpfs", str(folder)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {mounted.stderr.decode().strip()}")
    yield folder
    subprocess.run(["umount", "-l", str(folder)], check=True)


@pytest.fixture
def unwritable(public, request):
    """A folder that the runs made with user="other" cannot write into."""
    folder = public / f"read-only-{request.node.name}"
    folder.mkdir()
    os.chmod(folder, 0o555)
    return folder


@pytest.fixture(scope="module")
def public_scene(small_scene, public):
    """The small scene's HRG and DSM and a block with mass points and control points, readable by every user."""
    folder = public / "scene"
    folder.mkdir()
    image = folder / "HRG"
    shutil.copytree(os.path.dirname(small_scene["images"]["HRG"]["imagery"]), image)
    shutil.copy(small_scene["dsm"], folder / "dsm.tif")
    path = str(folder / "block.gpkg")
    Block.create(
        path, Block.open_images([small_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")]), height=300.0
    )
    cp.import_csv(Block(path), small_scene["points"], suffix="_meas")
    ids = [r["id"] for r in Block(path).images()]
    pts = np.zeros(50, POINT_DTYPE)
    pts["id"], pts["group"] = np.arange(50), 3
    obs = np.zeros(150, OBS_DTYPE)
    obs["point_id"], obs["image_id"] = np.repeat(np.arange(50), 3), np.tile(ids, 50)
    obs["col"], obs["row"] = 100.0 + np.repeat(np.arange(50), 3), 200.0
    Block(path).store_points(MultiPoints(pts, obs), "mass_points")
    for name in ("HRS1", "HRS2"):
        shutil.copytree(os.path.dirname(small_scene["images"][name]["imagery"]), folder / name)
    return {
        "image": str(image / "IMAGERY.TIF"),
        "dsm": str(folder / "dsm.tif"),
        "block": path,
        "images": [str(folder / n / "IMAGERY.TIF") for n in ("HRG", "HRS1", "HRS2")],
    }


def test_orthorectify_onto_a_full_disk(runner, public_scene, tiny_disk):
    # 0.5 m cells: 6000 x 6000 bytes of image, twice what the 3 MB disk holds
    result = runner(
        "pushbroom:orthorectify",
        "--",
        f"IMAGE={public_scene['image']}",
        f"DEM={public_scene['dsm']}",
        "CELL_SIZE=0.5",
        f"OUTPUT={tiny_disk / 'ortho.tif'}",
    )
    failed_once(result, "No space left on device")
    assert "the disk is full" in result.stderr
    assert os.listdir(tiny_disk) == []  # no corrupt file under the final name, no leftover


def test_interpolatedem_onto_a_full_disk(runner, tiny_disk, tmp_path):
    rng = np.random.default_rng(0)
    n = 20000
    x, y = rng.uniform(500000, 501000, n), rng.uniform(4000000, 4001000, n)
    lon, lat = reproject(x, y, srs(32616), wgs84())
    cloud, _, _ = write_point_cloud(str(tmp_path / "cloud.las"), lon, lat, rng.normal(300, 20, n), {}, crs="EPSG:32616")
    # 0.25 m cells of a rough surface: 4000 x 4000 Float32 that hardly compress, far over 3 MB
    result = runner("pushbroom:interpolatedem", "--", f"INPUT={cloud}", "CELL=0.25", f"OUTPUT={tiny_disk / 'dem.tif'}")
    failed_once(result, "No space left on device")
    assert os.listdir(tiny_disk) == []


ALGORITHMS = {
    "createblock": lambda s, out: [
        "pushbroom:createblock",
        "--",
        *[f"IMAGES={i}" for i in s["images"]],
        f"OUTPUT={out / 'block.gpkg'}",
    ],
    "simulatescene": lambda s, out: ["pushbroom:simulatescene", "--", "SIZE_KM=3", f"OUTPUT={out / 'scene'}"],
    "orthorectify": lambda s, out: [
        "pushbroom:orthorectify",
        "--",
        f"IMAGE={s['image']}",
        f"DEM={s['dsm']}",
        f"OUTPUT={out / 'ortho.tif'}",
    ],
    "exportpoints": lambda s, out: ["pushbroom:exportpoints", "--", f"BLOCK={s['block']}", f"OUTPUT={out / 'p.csv'}"],
    "intersectpoints": lambda s, out: [
        "pushbroom:intersectpoints",
        "--",
        f"BLOCK={s['block']}",
        f"OUTPUT={out / 'cloud.las'}",
    ],
}


@pytest.mark.parametrize("name", sorted(ALGORITHMS))
def test_an_output_folder_that_cannot_be_written(runner, public_scene, unwritable, name):
    result = runner(*ALGORITHMS[name](public_scene, unwritable), user="other")
    failed_once(result, "Permission denied (no permission to write there: choose a folder you can write to)")
    assert os.listdir(unwritable) == []


@pytest.mark.parametrize("crs", ["EPSG:999999", "GEOGCS[nonsense"])
def test_an_unknown_crs_is_an_error_not_the_default(runner, public_scene, small_scene, tmp_path, crs):
    path = copy_block(public_scene["block"], tmp_path)
    result = runner(
        "pushbroom:importpoints",
        "--",
        f"BLOCK={path}",
        f"INPUT={small_scene['points']}",
        "MEAS_SUFFIX=_meas",
        f"CRS={crs}",
    )
    failed_once(result, "is not a coordinate reference system QGIS knows")
    result = runner(
        "pushbroom:orthorectify",
        "--",
        f"IMAGE={public_scene['image']}",
        f"DEM={public_scene['dsm']}",
        f"CRS={crs}",
        f"OUTPUT={tmp_path / 'o.tif'}",
    )
    failed_once(result, "is not a coordinate reference system QGIS knows")
    assert not (tmp_path / "o.tif").exists()


def test_a_geopackage_of_another_program(runner, tmp_path):
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(tmp_path / "other.gpkg"))
    layer = ds.CreateLayer("images", None, ogr.wkbNone)
    layer.CreateField(ogr.FieldDefn("title", ogr.OFTString))
    ds = layer = None
    result = runner("pushbroom:matchpoints", "--", f"BLOCK={tmp_path / 'other.gpkg'}")
    failed_once(result, "is not a Pushbroom block")


def test_a_truncated_point_file_is_named(runner, public_scene, tmp_path):
    path = copy_block(public_scene["block"], tmp_path)
    part = Block(path).point_parts()[0]
    data = open(part, "rb").read()
    with open(part, "wb") as f:
        f.write(data[: len(data) // 2])
    result = runner("pushbroom:intersectpoints", "--", f"BLOCK={path}", f"OUTPUT={tmp_path / 'c.las'}")
    failed_once(result, f"the point file {part} is damaged")
    assert not (tmp_path / "c.las").exists()


def copy_block(source, folder):
    """A copy of the block `source` and its point folders in `folder`."""
    for name in os.listdir(os.path.dirname(source)):
        if name.startswith(os.path.basename(source)[: -len(".gpkg")] + "."):
            copy = shutil.copytree if os.path.isdir(os.path.join(os.path.dirname(source), name)) else shutil.copy
            copy(os.path.join(os.path.dirname(source), name), folder / name)
    return str(folder / os.path.basename(source))


@pytest.fixture
def control_block(public_scene, tmp_path):
    return copy_block(public_scene["block"], tmp_path)


def stored_models(path):
    with sqlite3.connect(path) as db:
        return db.execute("SELECT model FROM images ORDER BY fid").fetchall()


def test_bundleadjust_on_a_block_another_program_keeps_locked(runner, control_block):
    before = stored_models(control_block)
    holder = sqlite3.connect(control_block, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")  # another program's write transaction
    try:
        result = runner("pushbroom:bundleadjust", "--", f"BLOCK={control_block}", "FREE=look:0", "USE_TIE_POINTS=false")
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    text = failed_once(result, f"process {os.getpid()}) keeps it locked")  # the program holding the lock, named
    assert "another program (" in text and "nothing was stored" in text
    assert "Adjustment:" not in result.stdout  # refused before it computed
    assert stored_models(control_block) == before


def test_bundleadjust_refuses_results_of_a_control_set_replaced_meanwhile(
    pushbroom_provider, control_block, small_scene, monkeypatch
):
    """importpoints replaces the control set while the adjustment computes: nothing of the old set's
    adjustment is stored (the measurement window's "Adjust now" runs the same algorithm)."""
    from pushbroom.algorithms.steps import adjust_block as bundle_adjust

    before = stored_models(control_block)
    real = bundle_adjust.adjust_with_components

    def import_meanwhile(*args, **kwargs):
        result = real(*args, **kwargs)
        cp.import_csv(Block(control_block), small_scene["points"], suffix="_meas", check_ids=["P001", "P002"])
        return result

    monkeypatch.setattr(bundle_adjust, "adjust_with_components", import_meanwhile)
    with pytest.raises(QgsProcessingException, match="control points changed while this step computed"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": control_block, "FREE": "look:0", "USE_TIE_POINTS": False})
    assert stored_models(control_block) == before
    with sqlite3.connect(control_block) as db:
        tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    assert "measurement_residuals" not in tables
    # the same run without the interference stores its results
    monkeypatch.setattr(bundle_adjust, "adjust_with_components", real)
    processing.run("pushbroom:bundleadjust", {"BLOCK": control_block, "FREE": "look:0", "USE_TIE_POINTS": False})
    assert stored_models(control_block) != before
    assert len(Block(control_block).points()) == 50
