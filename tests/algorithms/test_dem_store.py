"""dem_store.py: a DEM read by bands and windows gives what the whole grid in memory gives (GDAL's own
in-memory warp, dem.Dem's bilinear and image_to_dem), on the small scene's DSM and a UTM copy of it."""

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import dem_store, sensors
from pushbroom.algorithms.dem_store import read_dem


@pytest.fixture(scope="module")
def utm_dsm(small_scene, tmp_path_factory):
    path = str(tmp_path_factory.mktemp("dem") / "dsm_utm.tif")
    gdal.Warp(
        path, small_scene["dsm"], dstSRS="EPSG:32616", xRes=5.0, yRes=5.0, resampleAlg="bilinear", dstNodata=-9999
    )
    return path


@pytest.fixture
def small_bands(monkeypatch):
    """Bands and blocks far smaller than the scene, so that every reading crosses many of them."""
    monkeypatch.setattr(dem_store, "ROWS", 37)
    monkeypatch.setattr(dem_store, "BLOCK", 64)


def test_a_warped_dem_is_gdals_in_memory_warp(utm_dsm, tmp_path, small_bands):
    stored = dem_store.store_dem(utm_dsm, tmp_path)
    # the plain way: the whole raster warped in memory by GDAL
    reference = gdal.Warp(
        "",
        utm_dsm,
        format="MEM",
        dstSRS="EPSG:4326",
        resampleAlg="bilinear",
        outputType=gdal.GDT_Float64,
        srcNodata=-9999,
        dstNodata=float("nan"),
    )
    expected = reference.GetRasterBand(1).ReadAsArray()
    assert stored.geotransform == pytest.approx(reference.GetGeoTransform(), abs=1e-12)
    got = stored.whole().heights
    assert (np.isnan(got) == np.isnan(expected)).mean() > 0.999
    both = np.isfinite(got) & np.isfinite(expected)
    assert np.abs(got - expected)[both].max() < 1e-6  # GDAL's chunks of the same bilinear warp
    assert stored.height_range == (np.nanmin(got), np.nanmax(got))
    assert not any(name.startswith("dem-") for name in (p.name for p in tmp_path.iterdir()))  # intermediates go


def test_heights_and_ranges_by_blocks_are_the_whole_grids(small_scene, tmp_path, small_bands):
    stored = dem_store.store_dem(small_scene["dsm"], tmp_path)
    whole = read_dem(small_scene["dsm"])
    np.testing.assert_array_equal(stored.whole().heights, whole.heights)
    west, south, east, north = whole.bounds
    rng = np.random.default_rng(5)
    lon = rng.uniform(west - 0.01, east + 0.01, 20000)  # some outside: NaN as the whole grid's
    lat = rng.uniform(south - 0.01, north + 0.01, 20000)
    # a window's origin is the grid's plus whole cells: the same bilinear to rounding
    np.testing.assert_allclose(stored.height(lon, lat), whole.height(lon, lat), rtol=0, atol=1e-8)
    rows, cols = (40, 333), (7, 250)
    window = whole.heights[rows[0] : rows[1], cols[0] : cols[1]]
    assert stored.cells_range(rows, cols) == (np.nanmin(window), np.nanmax(window))


def test_rays_meet_the_stored_dem_where_they_meet_the_whole_one(small_scene, tmp_path, small_bands):
    stored = dem_store.store_dem(small_scene["dsm"], tmp_path)
    whole = read_dem(small_scene["dsm"])
    for name in ("HRG", "HRS1"):
        model = sensors.load(small_scene["images"][name]["imagery"])
        cols, rows = model.size
        c, r = np.random.default_rng(6).uniform(0, 1, (2, 40)) * [[cols], [rows]]
        got = np.array(stored.ground(model, c, r))
        expected = np.array(model.image_to_dem(c, r, whole))
        # each ray searched in its own window: the same crossing, refined to image_to_dem's 1 mm tolerance
        np.testing.assert_allclose(got[2], expected[2], atol=2e-3)
        np.testing.assert_allclose(got[:2], expected[:2], atol=1e-7)
