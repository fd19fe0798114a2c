"""A step's log under qgis_process, read through a pipe as a script's log or a batch system reads it, on a Dask
cluster without workers (plugin/console.py, algorithms/dask_backend.py): each line arrives as it is written, not
at the end; the error is printed once, in our words, with no traceback and no Python warning."""
import re
import subprocess
import time

import numpy as np
import pytest

from pushbroom.algorithms.crs import reproject, srs, wgs84
from pushbroom.algorithms.surface.pointcloud import write_point_cloud
from tests.helpers.dask_cluster import Cluster
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env

WAIT = 8.0


@pytest.mark.slow
def test_lines_arrive_as_written_and_the_error_once(tmp_path):
    rng = np.random.default_rng(0)
    x, y = rng.uniform(500000, 501000, 2000), rng.uniform(4000000, 4001000, 2000)
    lon, lat = reproject(x, y, srs(32616), wgs84())
    cloud, _, _ = write_point_cloud(str(tmp_path / "cloud.las"), lon, lat, rng.normal(300, 20, 2000), {},
                                    crs="EPSG:32616")
    env = dict(qgis_process_env(tmp_path / "profile"), PYTHONWARNINGS="ignore:setapi:DeprecationWarning")
    arrived = []
    with Cluster(tmp_path) as cluster:
        run = subprocess.Popen([QGIS_PROCESS, "run", "pushbroom:interpolatedem", "--", f"INPUT={cloud}", "CELL=10",
                                "EXECUTION=2", f"DASK_ADDRESS={cluster.address}", f"DASK_WAIT={WAIT}",
                                f"OUTPUT={tmp_path / 'dem.tif'}"],
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            for line in run.stdout:
                arrived.append((time.monotonic(), line.rstrip("\n")))
            run.wait(60)
        finally:
            run.kill()
    end = time.monotonic()
    log = "\n".join(line for _, line in arrived)
    assert run.returncode == 1
    waiting = [t for t, line in arrived if f"has no worker: waiting up to {WAIT:g} s for one" in line]
    # the line of the wait left as it was written, the wait's length before the step's end (a block-buffered
    # pipe gave it with the error, at the end)
    assert len(waiting) == 1 and end - waiting[0] > WAIT / 2
    said = f"no worker joined the Dask cluster at {cluster.address} within {WAIT:g} s (0 workers connected)"
    assert log.count(said) == 1 and "nothing was stored" in log
    assert not re.search(r"Traceback|\w+Warning\b|CancelledError|TimeoutError", log), log
    assert not (tmp_path / "dem.tif").exists()
