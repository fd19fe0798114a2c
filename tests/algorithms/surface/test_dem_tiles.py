"""The tiled DEM (algorithms/surface/dem_tiles.py) against the whole cloud's (tin_dem.interpolate_dem),
between tilings, and between executions, on tests/helpers/dem_cloud.py's cloud gridded at 10 m."""

import glob
import os
import signal
import threading
import time

import numpy as np
import pytest

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.errors import CancelledError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.surface import dem_tiles, pointcloud
from pushbroom.algorithms.surface.point_input import read_points
from pushbroom.algorithms.surface.tin_dem import DemParams, interpolate_dem
from tests.helpers.dem_cloud import UTM31, read_raster, surface, write_cloud
from tests.helpers.feedback import Feedback
from tests.helpers.processes import worker_processes


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    return write_cloud(tmp_path_factory.mktemp("cloud") / "cloud.las")


read = read_raster


def run(cloud, path, tile, execution=Execution("threads", 1), **kwargs):
    return dem_tiles.dem_from_point_cloud(
        str(cloud), str(path), DemParams(cell=10.0, tile=tile, execution=execution, **kwargs)
    )


def test_one_tile_is_the_whole_clouds_dem(cloud, tmp_path):
    result = run(cloud, tmp_path / "one.tif", 4096)
    assert result.tiles == 1
    whole = interpolate_dem(read_points(str(cloud)), DemParams(cell=10.0))
    heights, transform, overviews = read(tmp_path / "one.tif")
    assert transform == whole.grid.geotransform and overviews == 1
    expected = np.where(np.isfinite(whole.heights), whole.heights.astype(np.float32), np.nan)
    np.testing.assert_array_equal(heights, expected)
    assert result.removed == whole.removed and result.points == whole.points
    assert sum(result.removed) > 0 and result.points + sum(result.removed) == len(read_points(str(cloud)).x)
    assert 0.9 < result.defined < 1.0  # the hole is a gap


def test_sixteen_tiles_leave_no_seam(cloud, tmp_path):
    one = run(cloud, tmp_path / "one.tif", 4096)
    sixteen = run(cloud, tmp_path / "sixteen.tif", 75)
    assert (one.tiles, sixteen.tiles) == (1, 16) and sixteen.max_edge == one.max_edge
    # each point counted once, by the tile that owns it; the filter may decide otherwise on the outer edge
    assert sixteen.points + sum(sixteen.removed) == one.points + sum(one.removed)
    assert abs(sixteen.points - one.points) <= 1e-4 * one.points
    a, _, _ = read(tmp_path / "one.tif")
    b, _, _ = read(tmp_path / "sixteen.tif")
    both = np.isfinite(a) & np.isfinite(b)
    # the filter's spread is the whole cloud's in both; only on the cloud's outer edge, where the convex hull's
    # long triangles are the whole cloud's in one run and a tile's own in the other, can a decision change
    assert abs(sum(sixteen.removed) - sum(one.removed)) <= 0.01 * sum(one.removed)
    rows, cols = np.indices(a.shape)
    inner = np.minimum(np.minimum(rows, a.shape[0] - 1 - rows), np.minimum(cols, a.shape[1] - 1 - cols)) >= 2
    np.testing.assert_array_equal(a[inner], b[inner])
    dh = np.abs(a - b)[both]
    rows, cols = np.indices(a.shape)
    near = lambda index: np.minimum(index % 75, 74 - index % 75) < 3
    border = (near(rows) | near(cols))[both]
    p99_border, p99_inside = np.percentile(dh[border], 99), np.percentile(dh[~border], 99)
    print(
        f"1 vs 16 tiles: median |dh| {np.median(dh):.2e} m, p99 along the tile borders {p99_border:.2e} m, "
        f"away from them {p99_inside:.2e} m"
    )
    assert np.median(dh) <= 0.01
    assert p99_border <= max(p99_inside, 1e-6)


def test_a_strip_narrower_than_a_tile(cloud, tmp_path):
    points = read_points(str(cloud))
    strip = points.x < 500000.0 + 500.0  # 50 x 300 cells in tiles of 75: 1 x 4 tiles
    path = tmp_path / "strip.las"
    pointcloud.write_las(
        path,
        points.x[strip],
        points.y[strip],
        points.z[strip],
        {"sigma_h": points.fields["sigma_h"][strip]},
        points.srs,
    )
    result = run(path, tmp_path / "strip.tif", 75, k=0)
    assert result.tiles == 4
    whole = interpolate_dem(read_points(str(path)), DemParams(cell=10.0, k=0))
    heights, transform, _ = read(tmp_path / "strip.tif")
    assert transform == whole.grid.geotransform
    np.testing.assert_array_equal(
        heights, np.where(np.isfinite(whole.heights), whole.heights.astype(np.float32), np.nan)
    )


def test_a_tile_whose_points_span_no_area_is_a_gap(tmp_path):
    x, y = np.meshgrid(np.arange(0.0, 1000.0, 12.0), np.arange(0.0, 1000.0, 12.0))
    x, y = 500000.0 + np.append(x.ravel(), 5000.0), 4800000.0 + np.append(y.ravel(), 0.0)  # one point far east
    z = surface(x, y)
    pointcloud.write_las(tmp_path / "c.las", x, y, z, {}, srs(UTM31))
    result = run(tmp_path / "c.las", tmp_path / "dem.tif", 100)
    heights, _, _ = read(tmp_path / "dem.tif")
    assert np.isfinite(heights[:, :100]).mean() > 0.9 and not np.isfinite(heights[:, 200:]).any()
    assert result.points == len(x)


@pytest.mark.slow
def test_every_execution_gives_the_same_dem(cloud, tmp_path):
    paths = {}
    for backend in ("threads", "processes", "dask"):
        paths[backend] = tmp_path / f"{backend}.tif"
        run(cloud, paths[backend], 75, Execution(backend, 2))
    reference, _, _ = read(paths["threads"])
    for backend in ("processes", "dask"):
        np.testing.assert_array_equal(read(paths[backend])[0], reference)


@pytest.mark.slow
def test_a_killed_dask_worker_leaves_the_same_dem(cloud, tmp_path):
    """kill -9 of a worker process of the LocalCluster once three tiles are written: the run completes
    (Dask runs the lost tasks again) and its DEM is the undisturbed run's."""
    reference = tmp_path / "reference.tif"
    run(cloud, reference, 32)
    killed = []

    def kill_a_worker():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not killed:
            if len(glob.glob(str(tmp_path / ".killed.*" / "dem-*.tif"))) >= 3:
                workers = worker_processes(os.getpid())
                if workers:
                    os.kill(workers[0], signal.SIGKILL)
                    killed.append(workers[0])
            time.sleep(0.01)

    thread = threading.Thread(target=kill_a_worker)
    thread.start()
    result = run(cloud, tmp_path / "killed.tif", 32, Execution("dask", 2))
    thread.join()
    assert killed and result.tiles == 100
    np.testing.assert_array_equal(read(tmp_path / "killed.tif")[0], read(reference)[0])


def test_the_precision_raster_is_tiled_too(cloud, tmp_path):
    params = DemParams(cell=10.0, tile=75)
    dem_tiles.dem_from_point_cloud(
        str(cloud), str(tmp_path / "dem.tif"), params, precision_path=str(tmp_path / "precision.tif")
    )
    whole = interpolate_dem(read_points(str(cloud)), DemParams(cell=10.0), precision=True)
    precision, _, _ = read(tmp_path / "precision.tif")
    defined = np.isfinite(precision) & np.isfinite(whole.precision)
    assert defined.mean() > 0.9
    # the same but where the tiles' blunder filters removed other points (a local robust sigma)
    assert np.mean(np.abs(precision[defined] - whole.precision[defined]) <= 1e-3) > 0.999


def test_a_cancel_leaves_no_dem_and_no_work_files(cloud, tmp_path):
    with pytest.raises(CancelledError):
        dem_tiles.dem_from_point_cloud(
            str(cloud), str(tmp_path / "dem.tif"), DemParams(cell=10.0, tile=75), feedback=Feedback(cancel_at=50)
        )
    assert list(tmp_path.iterdir()) == []
