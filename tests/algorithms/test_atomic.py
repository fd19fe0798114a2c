"""atomic.py, the one place that makes a write safe: a full disk (a real tiny tmpfs where mounting is
allowed, else skipped with the reason; a fake ENOSPC always), GDAL's failures on close, permissions and
paths, and the leftovers of killed writers."""

import errno
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from pushbroom.algorithms import atomic
from pushbroom.algorithms.block.points import save_arrays
from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.errors import StorageError
from pushbroom.algorithms.matching.points import MultiPoints
from pushbroom.algorithms.surface.geotiff import write_float_raster


@pytest.fixture
def tiny_disk(tmp_path):
    """A 3 MB tmpfs (unmounted afterwards), or skip where this user may not mount."""
    folder = tmp_path / "tiny"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=3m", "tmpfs", str(folder)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (needs root): {mounted.stderr.decode().strip()}")
    yield folder
    subprocess.run(["umount", "-l", str(folder)], check=True)  # lazy: a failed test may leave a file open


def noise(shape, seed=0):
    return np.random.default_rng(seed).normal(size=shape)


def test_geotiff_on_a_full_disk_fails_clearly_and_leaves_nothing(tiny_disk):
    target = tiny_disk / "dem.tif"
    # 2000 x 2000 Float32 noise does not compress: 16 MB on a 3 MB disk
    with pytest.raises(StorageError, match=r"cannot write the output .*dem\.tif: .*No space left.*the disk is full"):
        write_float_raster(target, noise((2000, 2000)), (0, 1, 0, 0, 0, -1), srs(32616))
    assert os.listdir(tiny_disk) == []  # neither the target nor a temporary file


def test_gdal_failure_on_close_fails_the_write(tiny_disk):
    """The last tiles and the overviews are written when the dataset closes: their failure must count."""
    from osgeo import gdal

    gdal.UseExceptions()
    target = tiny_disk / "x.tif"
    with pytest.raises(StorageError, match="No space left"):
        with atomic.atomic_path(target) as tmp:
            with atomic.closing(
                gdal.GetDriverByName("GTiff").Create(tmp, 1500, 1500, 1, gdal.GDT_Float64, ["TILED=YES"])
            ) as ds:
                ds.GetRasterBand(1).WriteArray(noise((1500, 1500)))  # cached: written on close
    assert not target.exists()


def test_a_fake_enospc_is_a_storage_error(tmp_path, monkeypatch):
    def full(*_args, **_kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    with pytest.raises(
        StorageError, match=r"cannot write the point file .*p\.npz: No space left on device \(the disk is full"
    ):
        save_arrays(tmp_path / "p.npz", MultiPoints())
    assert os.listdir(tmp_path) == []


def test_a_late_enospc_at_fsync_keeps_the_old_file(tmp_path, monkeypatch):
    """A file system that reports a full disk only when flushing (NFS, quotas): the old file stays."""
    target = tmp_path / "t.txt"
    atomic.write_text(target, "old")

    def late(_fd):
        raise OSError(errno.EDQUOT, "Disk quota exceeded")

    monkeypatch.setattr(os, "fsync", late)
    with pytest.raises(StorageError, match="quota"):
        atomic.write_text(target, "new")
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["t.txt"]


def test_a_read_error_of_an_input_is_not_reported_as_a_write_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        with atomic.atomic_path(tmp_path / "out.txt"):
            open(tmp_path / "missing-input.txt")


def test_check_destination_names_the_problem(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(StorageError, match="a part of the path is a file, not a folder"):
        atomic.check_destination(blocker / "out.tif")
    with pytest.raises(StorageError, match="a folder of that name is in the way"):
        atomic.check_destination(tmp_path)
    assert atomic.check_destination(tmp_path / "new" / "out.tif") == str(tmp_path / "new")
    assert os.listdir(tmp_path / "new") == []  # the probe is gone


def test_a_file_is_never_written_over_what_is_not_a_regular_file(tmp_path):
    """A device node (/dev/full, which root could replace), a FIFO or a folder: refused before the body runs."""
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    for path, match in [
        (fifo, "it is a FIFO, not a regular file"),
        ("/dev/full", "it is a device, not a regular file"),
        (tmp_path, "a folder of that name is in the way"),
    ]:
        ran = []
        with pytest.raises(StorageError, match=match):
            with atomic.atomic_path(path) as tmp:
                ran.append(tmp)
        assert ran == []
    assert fifo.is_fifo() and os.path.exists("/dev/full") and sorted(os.listdir(tmp_path)) == ["fifo.csv"]


def test_a_folder_is_never_written_over_a_file(tmp_path):
    target = tmp_path / "scene"
    target.write_text("the user's file")
    with pytest.raises(StorageError, match="a file has that name, and only a folder is replaced"):
        with atomic.atomic_dir(target):
            pass
    assert target.read_text() == "the user's file" and os.listdir(tmp_path) == ["scene"]


def test_a_shapefile_is_written_with_its_companions(tmp_path):
    """The .shx, .dbf and .prj the driver writes beside the temporary name are renamed with it; a stale companion
    of the old file (here a .cpg) is removed, since it would describe the new file."""
    import numpy as np
    from osgeo import ogr

    from pushbroom.algorithms.adjustment.residual_vectors import VECTOR_DTYPE, write_residual_vectors

    vectors = np.zeros(3, VECTOR_DTYPE)
    vectors["x1"], vectors["name"] = [1.0, 2.0, 3.0], ["a", "b", "c"]
    (tmp_path / "r.cpg").write_text("LATIN1")
    write_residual_vectors(tmp_path / "r.shp", vectors, "EPSG:32632", 1.0)
    assert sorted(os.listdir(tmp_path)) == ["r.dbf", "r.prj", "r.shp", "r.shx"]
    ds = ogr.Open(str(tmp_path / "r.shp"))
    layer = ds.GetLayer()
    assert layer.GetFeatureCount() == 3 and layer.GetSpatialRef().GetAuthorityCode(None) == "32632"
    assert sorted(f["name"] for f in layer) == ["a", "b", "c"]


@pytest.mark.skipif(
    os.geteuid() == 0,
    reason="root writes into read-only folders (tests/plugin/test_faults_alg.py checks permissions as another user)",
)
def test_check_destination_of_a_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o555)
    with pytest.raises(StorageError, match="no permission to write there"):
        atomic.check_destination(folder / "out.tif")


def dead_pid():
    """The pid of a process that has ended (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_leftovers_of_a_dead_writer_are_cleaned_live_ones_kept(tmp_path):
    dead = tmp_path / f".dem.{atomic.HOST}-{dead_pid()}.0123abcd.part.tif"
    live = tmp_path / f".dem.{atomic.HOST}-{os.getpid()}.89abcdef.part.tif"
    young = tmp_path / ".dem.otherhost-1.00000000.part.tif"
    old = tmp_path / ".dem.otherhost-2.11111111.part.tif"
    for path in (dead, live, young, old):
        path.write_bytes(b"x")
    os.utime(old, (time.time() - atomic.STALE_SECONDS - 60,) * 2)
    found = {os.path.basename(item["path"]): item["stale"] for item in atomic.leftovers(tmp_path)}
    # a gone writer on this host, or another host's name older than STALE_SECONDS, is stale
    assert found == {dead.name: True, live.name: False, young.name: False, old.name: True}
    removed = atomic.clean_leftovers(tmp_path)
    assert sorted(map(os.path.basename, removed)) == sorted([dead.name, old.name])
    assert sorted(os.listdir(tmp_path)) == sorted([live.name, young.name])


def test_a_folder_swapped_out_by_a_killed_writer_is_put_back(tmp_path):
    swapped = tmp_path / f".scene.{atomic.HOST}-{dead_pid()}.0123abcd.old"
    (swapped / "x").mkdir(parents=True)
    (swapped / "x" / "truth.json").write_text("{}")
    atomic.clean_leftovers(tmp_path)
    assert os.listdir(tmp_path) == ["scene"] and (tmp_path / "scene" / "truth.json").read_text() == "{}"


def test_a_killed_simulation_leaves_a_part_folder_the_next_write_removes(tmp_path):
    """kill -9 of a simulation while it writes its products: the hidden .part folder is listed as stale
    and removed by the next write into that folder."""
    code = (
        "import sys\n"
        "from pushbroom.algorithms.simulation import SceneConfig, simulate_scene\n"
        "simulate_scene(SceneConfig.small(), sys.argv[1])\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "scene")])
    deadline = time.time() + 600
    while not any(".part" in name for name in os.listdir(tmp_path)):
        assert proc.poll() is None and time.time() < deadline, "the simulation ended before it wrote its products"
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    left = atomic.leftovers(tmp_path)
    assert len(left) == 1 and left[0]["stale"] and left[0]["pid"] == proc.pid
    assert not (tmp_path / "scene").exists()  # nothing under the final name
    atomic.write_text(tmp_path / "note.txt", "next run")
    assert os.listdir(tmp_path) == ["note.txt"]
