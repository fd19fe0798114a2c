"""The DEM step refuses a cell size that makes no raster of the cloud (issue 36: METHOD 1 with CELL=1e9 wrote a DEM
of one cell) or is given in the wrong unit, on a small cloud."""

import numpy as np
import pytest

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.surface import dem_tiles, pointcloud
from pushbroom.algorithms.surface.tin_dem import DemParams
from tests.helpers.dem_cloud import UTM31, surface


@pytest.fixture(scope="module")
def cloud(tmp_path_factory):
    """400 points over 1 x 1 km in UTM 31N."""
    x, y = np.meshgrid(np.arange(25.0, 1000.0, 50.0), np.arange(25.0, 1000.0, 50.0))
    x, y = 500000.0 + x.ravel(), 4800000.0 + y.ravel()
    path = tmp_path_factory.mktemp("small_cloud") / "c.las"
    pointcloud.write_las(path, x, y, surface(x, y), {}, srs(UTM31))
    return str(path)


@pytest.mark.parametrize("method", ["tin", "cells"])
def test_a_cell_larger_than_half_the_cloud_is_refused(cloud, tmp_path, method):
    with pytest.raises(
        InputError,
        match=r"a cell size of 1e\+09 metres makes the DEM a grid of 1 x 1 cells over "
        r"950 x 950 metres .*: give a cell size of at most 475 metres",
    ):
        dem_tiles.dem_from_point_cloud(cloud, str(tmp_path / "dem.tif"), DemParams(cell=1e9, method=method))
    assert not list(tmp_path.iterdir())  # nothing written, no work folder left


def test_metres_on_a_degree_crs_are_named(cloud, tmp_path):
    with pytest.raises(
        InputError,
        match=r"a cell size of 10 degrees makes the DEM a grid of 1 x 1 cells .*"
        r"is the cell size in metres\?",
    ):
        dem_tiles.dem_from_point_cloud(cloud, str(tmp_path / "dem.tif"), DemParams(cell=10.0, crs="EPSG:4326"))
    assert not list(tmp_path.iterdir())


def test_a_cloud_at_one_position_spans_no_area(tmp_path):
    # per-cell medians of points at one position would be a DEM of one cell: refused, saying why
    x, y = np.full(50, 500000.0), np.full(50, 4800000.0)
    path = tmp_path / "one.las"
    pointcloud.write_las(path, x, y, surface(x, y), {}, srs(UTM31))
    with pytest.raises(
        InputError,
        match=r"the data span 0 x 0 metres .*no area: the DEM needs data spread over at "
        r"least 2 x 2 cells",
    ):
        dem_tiles.dem_from_point_cloud(str(path), str(tmp_path / "dem.tif"), DemParams(cell=10.0, method="cells"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["one.las"]
