"""The block GeoPackage: contents, footprints, overwrite protection and cancel safety."""

import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from osgeo import ogr

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.geodesy import metres_per_degree
from tests.helpers.feedback import Feedback


@pytest.fixture
def spot5_product(spot5_dim, tmp_path):
    """A DIMAP product folder (metadata only) named like a scene."""
    folder = tmp_path / "HRG1"
    folder.mkdir()
    shutil.copy(spot5_dim, folder / "METADATA.DIM")
    return folder / "METADATA.DIM"


def producer_corners(dim):
    root = ET.parse(dim).getroot()
    return [
        (float(v.findtext("FRAME_LON")), float(v.findtext("FRAME_LAT")))
        for v in root.find("Dataset_Frame").findall("Vertex")
    ]


def test_block_holds_images_and_footprints(spot5_product, tmp_path):
    images = Block.open_images([str(spot5_product)])
    assert [name for name, *_ in images] == ["HRG1"]
    path = Block.create(tmp_path / "b.gpkg", images, height=0.0).path
    rows = Block(path).images()
    assert rows[0]["name"] == "HRG1" and rows[0]["model_kind"] == "spot_dimap"
    assert (rows[0]["cols"], rows[0]["rows"]) == (12000, 12000)
    assert rows[0]["sensor"] == "SPOT 5 HRG1"
    ds = ogr.Open(str(path))
    layer = ds.GetLayerByName("footprints")
    assert layer.GetSpatialRef().GetAuthorityCode(None) == "4326"
    feature = layer.GetNextFeature()
    ring = np.array(feature.GetGeometryRef().GetGeometryRef(0).GetPoints())
    # every producer corner (a pixel centre) lies within one pixel (~10 m) of a footprint vertex
    for lon, lat in producer_corners(spot5_product):
        me, mn = metres_per_degree(lat)
        d = np.hypot((ring[:, 0] - lon) * me, (ring[:, 1] - lat) * mn)
        assert d.min() < 10.0
    stored = Block(path).model(rows[0]["id"])
    lon, lat = images[0][3].image_to_ground(np.array([0.5, 6000.0]), np.array([0.5, 11999.5]), 0.0)
    assert np.array_equal(stored.image_to_ground(np.array([0.5, 6000.0]), np.array([0.5, 11999.5]), 0.0), (lon, lat))
    info = {f["key"]: f["value"] for f in ds.GetLayerByName("block_info")}
    assert info["default_crs"] == "EPSG:32645"  # UTM 45N for 87.9 E, 50.0 N


def test_existing_block_needs_overwrite(spot5_product, tmp_path):
    images = Block.open_images([str(spot5_product)])
    path = Block.create(tmp_path / "b.gpkg", images).path
    before = open(path, "rb").read()
    with pytest.raises(InputError, match="overwrite"):
        Block.create(path, images)
    assert open(path, "rb").read() == before
    Block.create(path, images, height=500.0, overwrite=True)
    assert open(path, "rb").read() != before


def test_cancel_leaves_existing_block_and_no_partial_file(spot5_product, tmp_path):
    other = shutil.copytree(spot5_product.parent, tmp_path / "other" / "HRG1")  # a second product, same name
    images = Block.open_images([str(spot5_product), str(other / "METADATA.DIM")])
    assert [n for n, *_ in images] == ["HRG1", "HRG1_2"]
    path = Block.create(tmp_path / "b.gpkg", images[:1]).path
    before = open(path, "rb").read()
    with pytest.raises(CancelledError):
        Block.create(path, images, overwrite=True, feedback=Feedback(cancel_after=1))
    assert open(path, "rb").read() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["HRG1", "b.gpkg", "other"]


def test_an_image_given_twice_is_refused(spot5_product, tmp_path):
    """Issue 36: one image twice made a block whose matching 'found' thousands of points without parallax."""
    (tmp_path / "links").mkdir()
    (tmp_path / "links" / "symbolic.DIM").symlink_to(spot5_product)
    (tmp_path / "links" / "hard.DIM").hardlink_to(spot5_product)
    for second in (
        spot5_product,
        tmp_path / "links" / "symbolic.DIM",
        tmp_path / "links" / "hard.DIM",
        tmp_path / "HRG1" / ".." / "HRG1" / "METADATA.DIM",
    ):
        with pytest.raises(
            InputError,
            match=rf"images 1 and 2 \({spot5_product} and {second}\) are (the same path|one "
            "file): a block holds each image once",
        ):
            Block.open_images([str(spot5_product), str(second)])
    # the product by its folder and by its metadata: one METADATA.DIM, one image
    with pytest.raises(
        InputError,
        match="orientations of images 1 and 2 .* are the same path: each image has an orientation of its own",
    ):
        Block.open_images([str(spot5_product.parent), str(spot5_product)])


@pytest.mark.parametrize("bad, message", [("block.txt", "GeoPackage"), (None, "at least one image")])
def test_bad_block_requests(spot5_product, tmp_path, bad, message):
    images = [] if bad is None else Block.open_images([str(spot5_product)])
    with pytest.raises(InputError, match=message):
        Block.create(tmp_path / (bad or "b.gpkg"), images)


def test_orientation_count_must_match(spot5_product):
    with pytest.raises(InputError, match="one per image"):
        Block.open_images([str(spot5_product)] * 2, [str(spot5_product)])


def test_model_loaded_from_product_folder_equals_metadata(spot5_product):
    a = sensors.load(spot5_product.parent)
    b = sensors.load(spot5_product)
    assert a.size == b.size
    assert np.allclose(a.image_to_ground(100.0, 200.0, 300.0), b.image_to_ground(100.0, 200.0, 300.0), atol=0)


def test_block_records_terrain_height_range_and_logs_steps(spot5_product, tmp_path):
    from pushbroom.algorithms.dem import Dem
    from pushbroom.algorithms.dem_store import stored_copy

    images = Block.open_images([str(spot5_product)])
    path = Block.create(tmp_path / "b.gpkg", images, height=250.0).path
    assert Block(path).height_range() == (-250.0, 750.0)
    heights = np.full((50, 50), 300.0)
    heights[10:20, 10:20] = 1200.0  # a mountain inside the footprint's box
    heights[0, 0] = 5000.0  # a peak outside it
    dem = stored_copy(Dem(heights, (87.0, 0.04, 0.0, 51.0, 0.0, -0.04)), tmp_path)
    path2 = Block.create(tmp_path / "d.gpkg", images, dem=dem).path
    assert Block(path2).height_range() == (300.0, 1200.0)
    Block(path).update_info({"mass_points_count": 12}, step="matchpoints", message="12 points")
    assert Block(path).info()["mass_points_count"] == "12"
    ds = ogr.Open(str(path))
    steps = [f["step"] for f in ds.GetLayerByName("run_log")]
    assert steps == ["createblock", "matchpoints"]
