"""Point cloud output (algorithms/surface/pointcloud.py): LAS/LAZ read back with laspy, GeoPackage
read back with OGR, coordinates checked against OSR transforms of the input points."""

import os

import numpy as np
import pytest
from osgeo import ogr, osr

from pushbroom.algorithms.errors import InputError, StorageError
from pushbroom.algorithms.surface import pointcloud as pc
from pushbroom.algorithms.surface.intersection import CONVERGED, OUTSIDE, Intersection
from tests.helpers.osr_oracle import utm

N = 500


@pytest.fixture
def points():
    """Points around Jacksboro, Tennessee (UTM zone 16 N) with their fields."""
    rng = np.random.default_rng(0)
    lon, lat, h = rng.uniform(-84.21, -84.17, N), rng.uniform(36.60, 36.63, N), rng.uniform(250, 650, N)
    fields = {
        "point_id": np.arange(N, dtype=np.int64) * 7,
        "group": rng.integers(1, 4, N).astype(np.uint8),
        "rho": rng.uniform(0.6, 1.0, N).astype(np.float32),
        "rays": rng.integers(2, 4, N).astype(np.uint8),
        "sigma_h": rng.uniform(0.5, 2.0, N).astype(np.float32),
    }
    return lon, lat, h, fields


def read_las(path):
    laspy = pc.laspy_module()
    las = laspy.read(path)
    wkt = [v for v in las.header.vlrs if isinstance(v, laspy.vlrs.known.WktCoordinateSystemVlr)]
    return las, wkt


def test_las_has_the_utm_crs_coordinates_and_fields(points, tmp_path):
    lon, lat, h, fields = points
    path, srs, fmt = pc.write_point_cloud(tmp_path / "cloud.las", lon, lat, h, fields)
    assert fmt == "las"
    las, wkt = read_las(path)
    assert len(wkt) == 1 and las.header.global_encoding.wkt
    assert las.header.version.minor == 4 and las.header.point_format.id == 6
    crs = osr.SpatialReference(wkt=wkt[0].string)
    assert "UTM zone 16N" in wkt[0].string and crs.GetAuthorityCode(None) == "32616"
    x, y = utm(lon, lat, 32616)
    assert len(las.points) == N
    np.testing.assert_allclose(las.x, x, atol=0.0006)
    np.testing.assert_allclose(las.y, y, atol=0.0006)
    np.testing.assert_allclose(las.z, h, atol=0.0006)
    for name, values in fields.items():
        np.testing.assert_array_equal(np.asarray(las[name]), values)
        assert np.asarray(las[name]).dtype == values.dtype
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporary left


def test_las_in_a_given_crs(points, tmp_path):
    lon, lat, h, fields = points
    path, _, _ = pc.write_point_cloud(tmp_path / "cloud.las", lon, lat, h, {}, crs="EPSG:32617")
    las, wkt = read_las(path)
    assert "UTM zone 17N" in wkt[0].string
    x, y = utm(lon, lat, 32617)
    np.testing.assert_allclose(las.x, x, atol=0.0006)
    path, _, _ = pc.write_point_cloud(tmp_path / "geo.las", lon, lat, h, {}, crs=4326)
    las, _ = read_las(path)
    np.testing.assert_allclose(las.x, lon, atol=1e-8)
    np.testing.assert_allclose(las.y, lat, atol=1e-8)


def test_laz(points, tmp_path):
    lon, lat, h, fields = points
    path, _, _ = pc.write_point_cloud(tmp_path / "cloud.laz", lon, lat, h, fields)  # lazrs: make setup
    las, wkt = read_las(path)
    assert "UTM zone 16N" in wkt[0].string and las.header.point_format.id == 6
    np.testing.assert_allclose(las.z, h, atol=0.0006)
    np.testing.assert_array_equal(np.asarray(las["group"]), fields["group"])


def test_laz_without_a_backend_is_a_clear_error(points, tmp_path, monkeypatch):
    laspy = pc.laspy_module()
    monkeypatch.setattr(laspy.LazBackend, "detect_available", staticmethod(lambda: ()))
    lon, lat, h, fields = points
    with pytest.raises(InputError, match="lazrs"):
        pc.write_point_cloud(tmp_path / "cloud.laz", lon, lat, h, fields)
    assert not os.listdir(tmp_path)


def test_geopackage(points, tmp_path):
    lon, lat, h, fields = points
    path, _, fmt = pc.write_point_cloud(tmp_path / "cloud.gpkg", lon, lat, h, fields)
    ds = ogr.Open(path)
    layer = ds.GetLayerByName(pc.GPKG_LAYER)
    assert fmt == "gpkg"
    assert layer.GetFeatureCount() == N and layer.GetGeomType() == ogr.wkbPoint25D
    assert layer.GetSpatialRef().GetAuthorityCode(None) == "32616"
    x, y = utm(lon, lat, 32616)
    got = np.array(
        [
            (
                f.GetGeometryRef().GetX(),
                f.GetGeometryRef().GetY(),
                f.GetGeometryRef().GetZ(),
                f["group"],
                f["rho"],
                f["point_id"],
            )
            for f in layer
        ]
    )
    np.testing.assert_allclose(got[:, 0], x, atol=1e-6)
    np.testing.assert_allclose(got[:, 1], y, atol=1e-6)
    np.testing.assert_allclose(got[:, 2], h, atol=1e-9)
    np.testing.assert_array_equal(got[:, 3], fields["group"])
    np.testing.assert_allclose(got[:, 4], fields["rho"], rtol=1e-6)
    np.testing.assert_array_equal(got[:, 5], fields["point_id"])


def test_format_choice_and_bad_input(points, tmp_path, monkeypatch):
    lon, lat, h, fields = points
    assert pc.output_format("a.LAZ", 10) == "laz" and pc.output_format("a.gpkg", 10) == "gpkg"
    assert pc.output_format("a.gpkg", 10**7, fmt="gpkg") == "gpkg"
    with pytest.raises(InputError, match=r"\.las, \.laz or \.gpkg"):
        pc.output_format("a.txt", 10)
    monkeypatch.setattr(pc, "GPKG_MAX_POINTS", N - 1)
    with pytest.raises(InputError, match="too many for a GeoPackage"):
        pc.write_point_cloud(tmp_path / "big.gpkg", lon, lat, h, fields)
    with pytest.raises(InputError, match="one value per point"):
        pc.write_point_cloud(tmp_path / "a.las", lon, lat, h, {"group": fields["group"][:-1]})
    with pytest.raises(InputError, match="finite"):
        pc.write_point_cloud(tmp_path / "a.las", np.r_[lon[:-1], np.nan], lat, h)
    with pytest.raises(InputError, match="unknown coordinate reference system"):
        pc.write_point_cloud(tmp_path / "a.las", lon, lat, h, crs="EPSG:99999999")
    assert not os.listdir(tmp_path)


def test_an_existing_file_survives_a_failed_write(points, tmp_path, monkeypatch):
    lon, lat, h, fields = points
    path, _, _ = pc.write_point_cloud(tmp_path / "cloud.las", lon, lat, h, fields)
    before = open(path, "rb").read()

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(pc.laspy_module().LasWriter, "write_points", broken)
    with pytest.raises(StorageError, match="cannot write the output .*cloud.las: disk full"):
        pc.write_point_cloud(path, lon[:10], lat[:10], h[:10])
    assert open(path, "rb").read() == before
    assert os.listdir(tmp_path) == ["cloud.las"]


def test_cloud_fields_keep_the_converged_points():
    n = 4
    cov = np.tile(np.diag([0.04, 0.09, 4.0]), (n, 1, 1))
    result = Intersection(
        np.array([3, 5, 8, 9]),
        np.zeros(n),
        np.zeros(n),
        np.zeros(n),
        np.array([2, 3, 3, 1]),
        np.array([CONVERGED, CONVERGED, OUTSIDE, CONVERGED], np.int8),
        np.ones(n, np.int32),
        np.array([0.5, 1.0, np.nan, 2.0]),
        np.zeros(n),
        cov,
    )
    fields = pc.cloud_fields(result, group=np.array([1, 3, 3, 2]), rho=np.array([0.7, 0.8, 0.9, 0.95]))
    np.testing.assert_array_equal(fields["point_id"], [3, 5, 9])
    np.testing.assert_array_equal(fields["group"], [1, 3, 2])
    np.testing.assert_array_equal(fields["rays"], [2, 3, 1])
    np.testing.assert_allclose(fields["sigma_h"], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(fields["rho"], [0.7, 0.8, 0.95], rtol=1e-6)
    np.testing.assert_allclose(fields["sigma0"], [0.5, 1.0, 2.0])
