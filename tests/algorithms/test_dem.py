"""dem.py: the bilinear kernel against scipy, the grid conventions, bad grids and file reading."""

import numpy as np
import pytest
from osgeo import gdal, osr
from scipy.interpolate import RegularGridInterpolator

from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError

GT = (10.0, 0.25, 0.0, 50.0, 0.0, -0.5)  # 0.25 x 0.5 degree cells, north-up


def small_dem(rng):
    return Dem(rng.normal(500.0, 200.0, (6, 9)), GT)


def test_bilinear_matches_scipy_between_cell_centres():
    dem = small_dem(np.random.default_rng(3))
    lon_c = GT[0] + (np.arange(9) + 0.5) * GT[1]  # cell centres carry the values
    lat_c = GT[3] + (np.arange(6) + 0.5) * GT[5]
    reference = RegularGridInterpolator((lat_c[::-1], lon_c), dem.heights[::-1], method="linear")
    rng = np.random.default_rng(4)
    lon = rng.uniform(lon_c[0], lon_c[-1], 500)
    lat = rng.uniform(lat_c[-1], lat_c[0], 500)
    np.testing.assert_allclose(dem.height(lon, lat), reference(np.column_stack([lat, lon])), rtol=0, atol=1e-9)
    # the centres themselves, the last row and column included
    lon_g, lat_g = np.meshgrid(lon_c, lat_c)
    np.testing.assert_allclose(dem.height(lon_g, lat_g), dem.heights, rtol=0, atol=1e-9)


def test_nan_outside_the_centres_and_next_to_nodata():
    z = np.arange(54.0).reshape(6, 9)
    z[2, 3] = np.nan
    dem = Dem(z, GT)
    assert np.isnan(dem.height(GT[0] + 0.1, 49.0))  # west of the first centre (half a cell of border)
    assert np.isnan(dem.height(GT[0] + 3.6 * GT[1], GT[3] + 2.4 * GT[5]))  # a cell next to the hole
    assert dem.height(GT[0] + 6.5 * GT[1], GT[3] + 4.5 * GT[5]) == z[4, 6]
    assert type(dem.height(10.5, 48.0)) is float and dem.height([[10.5]], [[48.0]]).shape == (1, 1)
    assert dem.height_range == (0.0, 53.0) and dem.bounds == (10.0, 47.0, 12.25, 50.0)


@pytest.mark.parametrize(
    "heights, gt, message",
    [
        (np.zeros(4), GT, "2-D grid"),
        (np.zeros((1, 5)), GT, "at least 2 x 2"),
        (np.zeros((3, 3)), (0.0, 1.0, 0.0), "6 finite numbers"),
        (np.zeros((3, 3)), (0.0, 1.0, 0.0, 0.0, 0.0, float("nan")), "6 finite numbers"),
        (np.zeros((3, 3)), (0.0, 1.0, 0.0, 0.0, 0.0, 1.0), "north-up"),
        (np.zeros((3, 3)), (0.0, 1.0, 0.1, 0.0, 0.0, -1.0), "north-up"),
        (np.full((3, 3), np.nan), GT, "no valid height"),
    ],
)
def test_unusable_grids_raise_input_error(heights, gt, message):
    with pytest.raises(InputError, match=message):
        Dem(heights, gt)


def test_read_dem_reads_nodata_as_nan_and_warps_projected_dems(tmp_path):
    gdal.UseExceptions()
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "geo.tif"), 4, 3, 1, gdal.GDT_Int16)
    ds.SetGeoTransform(GT)
    ds.SetSpatialRef(srs)
    ds.GetRasterBand(1).SetNoDataValue(-32768)
    z = np.arange(12, dtype=np.int16).reshape(3, 4)
    z[1, 2] = -32768
    ds.GetRasterBand(1).WriteArray(z)
    ds = None
    dem = read_dem(tmp_path / "geo.tif")
    assert dem.geotransform == GT and np.isnan(dem.heights[1, 2]) and dem.heights[2, 3] == 11.0
    utm = osr.SpatialReference()
    utm.ImportFromEPSG(32632)
    ds = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "utm.tif"), 20, 20, 1, gdal.GDT_Float32)
    ds.SetGeoTransform((500000.0, 30.0, 0.0, 5000000.0, 0.0, -30.0))
    ds.SetSpatialRef(utm)
    ds.GetRasterBand(1).Fill(123.0)
    ds = None
    dem = read_dem(tmp_path / "utm.tif")
    west, south, east, north = dem.bounds
    assert 8.9 < west < east < 9.1 and 45.1 < south < north < 45.2
    assert dem.height(0.5 * (west + east), 0.5 * (south + north)) == pytest.approx(123.0)
    with pytest.raises(InputError, match="cannot open DEM"):
        read_dem(tmp_path / "missing.tif")
