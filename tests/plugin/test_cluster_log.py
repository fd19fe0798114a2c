"""A step's log under qgis_process, read through a pipe as a script's log or a batch system reads it
(plugin/console.py, algorithms/dask_backend.py). On a Dask cluster without workers each line arrives as it is
written, not at the end, and the error is printed once, in our words, with no traceback and no Python warning. On a
Dask local cluster the log names its workers and the tiles each ran, with no warning and no leaked semaphore."""

import re
import subprocess
import threading
import time

import pytest

from tests.helpers.dask_cluster import Cluster
from tests.helpers.dem_cloud import write_cloud
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env

WAIT = 8.0


NOISE = r"Traceback|\w+Warning\b|CancelledError|TimeoutError|semaphore"


@pytest.fixture
def cloud(tmp_path):
    """The tiled DEM's test cloud (tests/helpers/dem_cloud.py, 3 x 3 km) and qgis_process's environment."""
    return (
        str(write_cloud(tmp_path / "cloud.las")),
        dict(qgis_process_env(tmp_path / "profile"), PYTHONWARNINGS="ignore:setapi:DeprecationWarning"),
    )


@pytest.mark.slow
def test_lines_arrive_as_written_and_the_error_once(tmp_path, cloud, figures):
    cloud, env = cloud
    arrived = []
    with Cluster(tmp_path) as cluster:
        run = subprocess.Popen(
            [
                QGIS_PROCESS,
                "run",
                "pushbroom:interpolatedem",
                "--",
                f"INPUT={cloud}",
                "CELL=10",
                "EXECUTION=2",
                f"DASK_ADDRESS={cluster.address}",
                f"DASK_WAIT={WAIT}",
                f"OUTPUT={tmp_path / 'dem.tif'}",
            ],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        watchdog = threading.Timer(300, run.kill)  # a hang fails the test, not the suite
        watchdog.start()
        try:
            for line in run.stdout:
                arrived.append((time.monotonic(), line.rstrip("\n")))
            end = time.monotonic()  # the output's end: the step's
            run.wait(60)
        finally:
            watchdog.cancel()
            run.kill()
    log = "\n".join(line for _, line in arrived)
    assert run.returncode == 1
    waiting = [t for t, line in arrived if f"has no worker: waiting up to {WAIT:g} s for one" in line]
    # the line of the wait left as it was written, the wait's length before the step's end (a block-buffered
    # pipe gave it with the error, at the end)
    assert len(waiting) == 1
    figures.report(
        "qgis_process into a pipe, a Dask cluster without workers: the wait's line before the step's end",
        end - waiting[0],
        "s",
        f"DASK_WAIT {WAIT:g} s",
    )
    assert end - waiting[0] > WAIT / 2
    said = f"no worker joined the Dask cluster at {cluster.address} within {WAIT:g} s (0 workers connected)"
    assert log.count(said) == 1 and "nothing was stored" in log
    assert not re.search(NOISE, log), log
    assert not (tmp_path / "dem.tif").exists()


@pytest.mark.slow
def test_a_local_cluster_logs_its_workers_and_their_tiles_and_nothing_else(tmp_path, cloud):
    cloud, env = cloud
    ran = subprocess.run(
        [
            QGIS_PROCESS,
            "run",
            "pushbroom:interpolatedem",
            "--",
            f"INPUT={cloud}",
            "CELL=20",
            "TILE=32",
            "EXECUTION=2",
            "WORKERS=2",
            f"OUTPUT={tmp_path / 'dem.tif'}",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    log = ran.stdout + ran.stderr
    assert ran.returncode == 0, log[-3000:]
    assert re.search(r"the Dask local cluster: 2 workers \(tcp://127\.0\.0\.1:\d+, tcp://127\.0\.0\.1:\d+\)", log)
    rounds = re.findall(r": (\d+) tasks on a Dask local cluster of 2 worker processes", log)
    tallies = re.findall(r"tasks per worker: (.*)", log)
    assert len(rounds) == len(tallies) >= 3  # the spacing, the blunder filter's iterations, the DEM's tiles
    assert [sum(map(int, re.findall(r" (\d+)(?:,|$)", t))) for t in tallies] == [int(n) for n in rounds]
    assert not re.search(NOISE, log), log
