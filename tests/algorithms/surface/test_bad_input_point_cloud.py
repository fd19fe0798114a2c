"""Bad point clouds for the DEM (issue 19), each an InputError in Pushbroom's words instead of Qhull's, PROJ's
or a misleading one: points all at one position or on one line; a file without a CRS or with an undefined one
(LAS without a CRS VLR, GeoPackage layer without SRS, a local CRS); coordinates that cannot be in their CRS
(degrees labelled UTM, metres labelled WGS 84, x and y swapped); an output CRS far from the points; missing
or unreadable files."""

import re

import numpy as np
import pytest
from osgeo import ogr, osr

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.surface import point_input, pointcloud, tin_dem
from tests.helpers.bad_inputs import las

UTM31 = 32631
#: 500 points over 1 km near Mont Ventoux, UTM 31N
X, Y, Z = np.random.default_rng(19).uniform((650_000, 4_890_000, 300), (651_000, 4_891_000, 400), (500, 3)).T


def gpkg(path, x, y, z, layer_srs):
    """A GeoPackage layer of 3-D points in `layer_srs` (None: written without one)."""
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(path))
    layer = ds.CreateLayer("points", layer_srs, ogr.wkbPoint25D)
    for xi, yi, zi in zip(x, y, z):
        feature = ogr.Feature(layer.GetLayerDefn())
        point = ogr.Geometry(ogr.wkbPoint25D)
        point.AddPoint(float(xi), float(yi), float(zi))
        feature.SetGeometry(point)
        layer.CreateFeature(feature)
    ds = None
    return str(path)


def test_identical_points_are_all_at_one_position(tmp_path):
    path = las(
        tmp_path / "same.las",
        np.full(100, 650_000.0),
        np.full(100, 4_890_000.0),
        np.full(100, 400.0),
        srs(UTM31).ExportToWkt(),
    )
    with pytest.raises(
        InputError,
        match=re.escape(
            "the 100 points of the point cloud are all at one position (x 650000.000, y 4890000.000): a TIN needs at "
            "least 3 points that are not on one line"
        ),
    ):
        tin_dem.interpolate_dem(point_input.read_points(path))


def test_points_on_one_line_or_at_two_positions(tmp_path):
    on_a_line = point_input.PointSet(X, 2 * X - 1e6, Z, srs(UTM31))
    two = point_input.PointSet(np.repeat([650_000.0, 650_010.0], 50), np.full(100, 4_890_000.0), Z[:100], srs(UTM31))
    for points in (on_a_line, two):
        with pytest.raises(
            InputError,
            match=r"points of the point cloud all lie on one line \(from x .* to x .*\): "
            "a TIN needs at least 3 points",
        ) as err:
            tin_dem.interpolate_dem(points)
        assert "Qhull" not in str(err.value) and "Qz" not in str(err.value)  # no qhull text


def test_a_las_without_a_crs_vlr_or_with_a_local_crs(tmp_path):
    local = osr.SpatialReference()
    local.SetLocalCS("site grid")
    for name, wkt, why in (
        ("none.las", None, "no WKT or EPSG GeoKey VLR"),
        ("empty.las", "", "its WKT VLR holds no CRS PROJ reads"),
        ("local.las", local.ExportToWkt(), "its CRS 'site grid' is a local or undefined one"),
    ):
        path = las(tmp_path / name, X, Y, Z, wkt)
        with pytest.raises(
            InputError, match=re.escape(f"the point cloud {path} has no coordinate reference system ({why}")
        ) as err:
            point_input.read_points(path)
        # what to do: give the CRS, or assign it with a command that works on this file
        assert f"pdal translate {path} out.las --writers.las.a_srs=EPSG:<code>" in str(err.value)
        assert len(point_input.read_points(path, crs=UTM31)) == 500  # a given CRS makes it readable


def test_a_geopackage_layer_without_srs(tmp_path):
    path = gpkg(tmp_path / "nosrs.gpkg", X, Y, Z, None)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"the point cloud {path} has no coordinate reference system (its CRS 'Undefined geographic SRS' is a "
            "local or undefined one, not placed on Earth), so where it lies is unknown: give the CRS its x, y are "
            f"in (the point cloud CRS parameter), or assign the CRS to the file (e.g. ogr2ogr -a_srs EPSG:<code> "
            f"out.gpkg {path}"
        ),
    ):
        point_input.read_points(path)


def degrees(n=500):
    """n points over 0.01 x 0.01 degrees near Mont Ventoux (lon, lat)."""
    rng = np.random.default_rng(5)
    return 5.27 + rng.uniform(0, 0.01, n), 44.17 + rng.uniform(0, 0.01, n)


def test_degrees_labelled_utm(tmp_path):
    lon, lat = degrees()
    path = las(tmp_path / "degrees.las", lon, lat, Z, srs(UTM31).ExportToWkt())
    # a 1 km cloud that spans 0.01 "m": degrees
    with pytest.raises(
        InputError,
        match=re.escape(f"the point cloud {path} spans only 0.00") + r"\d+ m in its CRS WGS "
        r"84 / UTM zone 31N \(x 5\.27.*\): these look like longitude/latitude degrees "
        r"labelled with a projected CRS.*\(EPSG:4326 for degrees\)",
    ):
        point_input.read_points(path)
    assert len(point_input.read_points(path, crs=4326)) == 500  # read as what they are, they pass


def test_metres_labelled_wgs84_and_swapped_axes(tmp_path):
    metres = gpkg(tmp_path / "metres.gpkg", X, Y, Z, srs(4326))
    with pytest.raises(InputError, match="which are not longitude/latitude degrees, but its CRS WGS 84 is geographic"):
        point_input.read_points(metres)
    swapped = gpkg(tmp_path / "swapped.gpkg", Y, X, Z, srs(UTM31))
    # northings as eastings put the centre near 40 E, 4.7 N: 34 degrees east of zone 31's 0 .. 6 E
    with pytest.raises(
        InputError,
        match=r"lies at longitude 39\.\d+, latitude 4\.\d+ according to its CRS WGS 84 / "
        r"UTM zone 31N, far from where that CRS is used \(longitude 0 .. 6, latitude "
        r"0 .. 84\)",
    ):
        point_input.read_points(swapped)


def test_an_output_crs_far_from_the_points():
    points = point_input.PointSet(X, Y, Z, srs(UTM31))
    # UTM 10N is a Pacific coast zone: 125 degrees west of the points
    with pytest.raises(
        InputError,
        match=r"the output CRS NAD83 / UTM zone 10N is used at longitude -126 .. -119.99, "
        r".*far from the point cloud \(longitude 4\.\d+, latitude 44\.\d+\)",
    ):
        tin_dem.interpolate_dem(points, tin_dem.DemParams(crs="EPSG:26910"))
    assert (
        tin_dem.interpolate_dem(points, tin_dem.DemParams(crs="EPSG:2154", cell=50.0, k=0)).points == 500
    )  # Lambert-93 covers it


def test_missing_and_unreadable_files(tmp_path):
    for name in ("missing.las", "missing.gpkg"):
        with pytest.raises(InputError, match=re.escape(f"{tmp_path / name}: the file does not exist; check the path")):
            point_input.read_points(tmp_path / name)
    (tmp_path / "text.las").write_text("x y z\n1 2 3\n")
    with pytest.raises(InputError, match="text.las: not a LAS/LAZ file laspy reads"):
        point_input.read_points(tmp_path / "text.las")


@pytest.mark.parametrize("ext", ["las", "laz"])
def test_a_point_cloud_cut_short_is_named_damaged(tmp_path, ext):
    """Before: laspy's "buffer size must be a multiple of element size", lazrs's "IoError: failed to fill whole
    buffer"."""
    lon, lat = degrees()
    path, _, _ = pointcloud.write_point_cloud(tmp_path / f"whole.{ext}", lon, lat, Z, crs=UTM31)
    data = open(path, "rb").read()
    facts = {
        "las": rf"its header announces 500 points, {len(data)} bytes with the header, but the file holds "
        rf"{len(data) // 2} bytes",
        "laz": rf"its compressed points end at byte {len(data) // 2}, before their chunk table at byte \d+",
    }
    for size, fact in ((len(data) // 2, facts[ext]), (100, r"it holds 100 bytes, less than a LAS header \(227\)")):
        cut = tmp_path / f"cut{size}.{ext}"
        cut.write_bytes(data[:size])
        for read in (point_input.read_points, lambda p: list(point_input.point_chunks(p, chunk=100))):
            with pytest.raises(
                InputError,
                match=rf"the point cloud {cut} is damaged: {fact}\. It was cut short .*: "
                r"copy it again, or make it again",
            ):
                read(cut)
    if ext == "laz":  # cut within the chunk table at its end: the points do not decode
        cut = tmp_path / "end.laz"
        cut.write_bytes(data[:-3])
        with pytest.raises(InputError, match=rf"the point cloud {cut} is damaged: its points cannot be read"):
            point_input.read_points(cut)


def test_a_valid_cloud_passes_the_checks(tmp_path):
    lon, lat = degrees()
    for crs in (UTM31, 4326, 2154):  # the points' own zone, degrees, a national projection
        path, _, _ = pointcloud.write_point_cloud(tmp_path / f"{crs}.las", lon, lat, Z, crs=crs)
        assert len(point_input.read_points(path)) == 500  # no check refuses a sound cloud
