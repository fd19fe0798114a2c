"""crs.transform hands PROJ its points in chunks: the chunks give every point as one call does. A CRS's area of
use and the unit of a cell size, as the steps check them."""

import numpy as np
import pytest

from pushbroom.algorithms import crs
from pushbroom.algorithms.errors import InputError


def test_chunked_transform_equals_one_call(monkeypatch):
    rng = np.random.default_rng(5)
    lonlat = np.column_stack([rng.uniform(2.0, 4.0, 1000), rng.uniform(43.0, 45.0, 1000), rng.uniform(0, 900, 1000)])
    whole = crs.transform(crs.srs(4979), crs.srs(4978), lonlat, "test points")
    monkeypatch.setattr(crs, "TRANSFORM_CHUNK", 64)  # 16 chunks, the last one short
    chunked = crs.transform(crs.srs(4979), crs.srs(4978), lonlat, "test points")
    assert chunked.shape == (1000, 3) and np.array_equal(chunked, whole)
    assert np.abs(np.linalg.norm(whole, axis=1) - 6.37e6).max() < 3e4  # ECEF radii: the transform ran


def test_area_of_use_takes_a_margin_and_wraps_the_antimeridian():
    # UTM 16N is used at longitude -90 .. -84: the simulated scene at -84.2 lies in it, zone 49N (108 .. 114)
    # is 190 degrees away; zone 60N (174 .. 180) holds a point 2 degrees across the antimeridian
    assert crs.within_area_of_use(crs.srs(32616), -84.2, 36.6)
    assert crs.within_area_of_use(crs.srs(32617), -84.2, 36.6)  # the next zone: within the margin
    assert not crs.within_area_of_use(crs.srs(32649), -84.2, 36.6)
    assert crs.within_area_of_use(crs.srs(32660), -178.0, 50.0)
    assert not crs.within_area_of_use(crs.srs(32660), -160.0, 50.0)
    assert crs.within_area_of_use(crs.srs(4326), 179.9, -89.0)  # the whole Earth


def test_a_grid_of_fewer_than_two_cells_names_the_unit():
    with pytest.raises(
        InputError,
        match=r"a cell size of 5 degrees makes the orthoimage a grid of 1 x 1 cells over "
        r"0\.03 x 0\.02 degrees .*at most 0\.01 degrees\. The CRS's unit is the "
        r"degree: is the cell size in metres\?",
    ):
        crs.check_grid_cells(1, 1, 5.0, crs.srs(4326), (0.03, 0.02), "the orthoimage")
    crs.check_grid_cells(2, 2, 0.01, crs.srs(4326), (0.03, 0.02), "the orthoimage")  # 2 x 2: a grid


def test_a_grid_of_too_many_cells_names_the_unit():
    # 0.0001 units of a UTM zone over 12 x 12 km (degrees given for metres): 1.2e8 x 1.2e8 cells
    side = round(12000 / 1e-4)
    with pytest.raises(
        InputError,
        match=rf"a cell size of 0\.0001 metres makes the DEM a grid of {side} x {side} "
        r"cells, too many: give a larger cell size\. The CRS's unit is metres: is the "
        r"cell size in degrees\?",
    ):
        crs.check_grid_cells(side, side, 1e-4, crs.srs(32617), (12000.0, 12000.0), "the DEM")
    crs.check_grid_cells(46340, 46340, 0.26, crs.srs(32617), (12000.0, 12000.0), "the DEM")  # 2^31 cells: taken
