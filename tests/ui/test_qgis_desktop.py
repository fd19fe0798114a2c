"""The plugin in the real QGIS desktop under Xvfb: a throw-away profile with the plugin installed (a link to the
repository) and enabled, and a startup script. tests/helpers/qgis_desktop_session.py opens the measurement
window from the toolbar action and measures 3 points of the simulated block; the block must hold them after
QGIS has quit. tests/helpers/desktop_execution_session.py runs the tiled DEM through Processing on local
worker processes and on a Dask local cluster: the workers must be Python interpreters, not QGIS, and the
DEMs those of threads."""

import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

import pushbroom
from pushbroom.algorithms.block import Block

REPO = pathlib.Path(pushbroom.__file__).resolve().parent
QGIS = "/usr/bin/qgis.bin"
SESSION = REPO / "tests" / "helpers" / "qgis_desktop_session.py"
TIMEOUT_S = 180
POINTS = 3


def make_profile(root):
    """Profiles folder with a profile "test": the plugin linked in and enabled (as `make setup` does for
    qgis_process)."""
    profile = root / "profiles" / "test"
    (profile / "python" / "plugins").mkdir(parents=True)
    (profile / "python" / "plugins" / "pushbroom").symlink_to(REPO)
    (profile / "QGIS").mkdir()
    (profile / "QGIS" / "QGIS3.ini").write_text("[PythonPlugins]\npushbroom=true\n")
    return root


def run_qgis(profiles, job_path, log_path, session=SESSION):
    """Run QGIS under Xvfb with the session script; returns its exit status (fails the test on a timeout)."""
    site = [p for p in sys.path if p.endswith("site-packages") and ".venv" in p]
    env = dict(
        os.environ,
        QT_QPA_PLATFORM="xcb",
        PUSHBROOM_SESSION=str(job_path),
        PYTHONPATH=os.pathsep.join(site + [str(REPO), os.environ.get("PYTHONPATH", "")]),
    )
    command = [
        "xvfb-run",
        "-a",
        QGIS,
        "--profiles-path",
        str(profiles),
        "--profile",
        "test",
        "--nologo",
        "--noversioncheck",
        "--code",
        str(session),
    ]
    with open(log_path, "w") as log:
        proc = subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            return proc.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    pytest.fail(f"QGIS did not finish within {TIMEOUT_S} s; its log:\n{log_path.read_text()[-5000:]}")


def job_points(rows, images):
    """The first POINTS points without blunders, with their true positions per block image id."""
    points = []
    for row in rows:
        if any(int(row[f"{name}_blunder"]) for name in images):
            continue
        points.append(
            {
                "name": row["id"],
                "lon": float(row["lon"]),
                "lat": float(row["lat"]),
                "h": float(row["h"]),
                "image": {str(i): [float(row[f"{name}_col"]), float(row[f"{name}_row"])] for name, i in images.items()},
            }
        )
    return points[:POINTS]


@pytest.mark.slow
@pytest.mark.skipif(not (shutil.which("xvfb-run") and os.path.exists(QGIS)), reason="needs xvfb-run and qgis.bin")
def test_measure_three_points_in_qgis_desktop(small_scene_block, tmp_path):
    template, rows = small_scene_block
    block_path = tmp_path / "block.gpkg"
    shutil.copy(template, block_path)
    images = {r["name"]: r["id"] for r in Block(block_path).images()}
    points = job_points(rows, images)
    job = tmp_path / "job.json"
    result_path, log_path = tmp_path / "result.json", tmp_path / "qgis.log"
    job.write_text(json.dumps({"block": str(block_path), "result": str(result_path), "points": points}))

    status = run_qgis(make_profile(tmp_path / "qgis"), job, log_path)
    log = log_path.read_text()
    assert result_path.exists(), f"the session script wrote no result (QGIS exit {status}); log:\n{log[-5000:]}"
    result = json.loads(result_path.read_text())
    assert not result["errors"], "\n".join(result["errors"]) + "\nQGIS log:\n" + log[-3000:]
    assert status == 0, log[-5000:]
    assert result["action"] and result["toolbars"] == ["Pushbroom"]
    assert result["windows"] == 1 and result["windows_after_second_trigger"] == 1
    name, count, renderer = result["layers_on_open"][0]
    assert len(result["layers_on_open"]) == 1 and renderer == "categorizedSymbol"
    assert result["layers_at_end"] == [[name, POINTS, renderer]]

    obs = Block(block_path).measurement_store().load()
    assert sorted(obs.points["name"]) == [p["name"] for p in points]
    first = min(images.values())
    for point in points:
        k = list(obs.points["name"]).index(point["name"])
        stored = obs.points[k]
        assert stored["role"] == "control"
        assert np.allclose(
            [stored["lon"], stored["lat"], stored["h"]], [point["lon"], point["lat"], point["h"]], rtol=0, atol=1e-9
        )
        meas = {int(m["image_id"]): (m["col"], m["row"]) for m in obs.measurements if m["point"] == k}
        assert sorted(meas) == sorted(images.values())
        for image_id, truth in point["image"].items():
            image_id = int(image_id)
            tolerance = 0.5 if image_id in result["transferred"][point["name"]] else 1e-6
            assert np.hypot(*np.subtract(meas[image_id], truth)) < tolerance, (point["name"], image_id)
        assert first not in result["transferred"][point["name"]]


@pytest.mark.slow
@pytest.mark.skipif(not (shutil.which("xvfb-run") and os.path.exists(QGIS)), reason="needs xvfb-run and qgis.bin")
def test_worker_processes_and_dask_from_qgis_desktop(tmp_path):
    from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
    from pushbroom.algorithms.surface.tin_dem import DemParams
    from pushbroom.algorithms.task_runtime import BACKENDS
    from tests.helpers.dem_cloud import read_raster, write_cloud

    cloud = write_cloud(tmp_path / "cloud.las")
    dem_from_point_cloud(str(cloud), str(tmp_path / "threads.tif"), DemParams(cell=10.0, tile=75))
    runs = {name: [BACKENDS.index(name), str(tmp_path / f"{name}.tif")] for name in ("processes", "dask")}
    job, result_path, log_path = tmp_path / "job.json", tmp_path / "result.json", tmp_path / "qgis.log"
    job.write_text(json.dumps({"cloud": str(cloud), "result": str(result_path), "runs": runs}))
    status = run_qgis(
        make_profile(tmp_path / "qgis"), job, log_path, REPO / "tests" / "helpers" / "desktop_execution_session.py"
    )
    log = log_path.read_text()
    assert result_path.exists(), f"the session script wrote no result (QGIS exit {status}); log:\n{log[-5000:]}"
    result = json.loads(result_path.read_text())
    assert result["errors"] == [], result["errors"]
    print(f"QGIS runs as {result['host']}; workers: {result['workers']}")
    for name in runs:
        workers = result["workers"][name]
        # Python interpreters, never QGIS itself; a worker may run a short-lived tool (Python's platform
        # module runs uname), which the watcher can catch
        assert any(os.path.basename(w).startswith("python3") for w in workers), (name, workers)
        assert not any(os.path.basename(w).startswith("qgis") for w in workers), (name, workers)
        np.testing.assert_array_equal(read_raster(runs[name][1])[0], read_raster(tmp_path / "threads.tif")[0])
