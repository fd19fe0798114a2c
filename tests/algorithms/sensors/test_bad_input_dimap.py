"""A SPOT DIMAP product without its raster (issue 19): METADATA.DIM present, IMAGERY.TIF deleted. Opening
the image names the missing raster and the product instead of GDAL's text."""

import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from tests.helpers.bad_inputs import product_without_raster


@pytest.fixture
def product(small_scene, tmp_path):
    return product_without_raster(small_scene, tmp_path)


def test_opening_the_deleted_raster_names_it_and_the_product(product):
    raster = product / "IMAGERY.TIF"
    for call in (
        lambda: Block.open_images([str(raster)]),
        lambda: sensors.load(raster),
        lambda: sensors.load(product / "METADATA.DIM", image=raster),
    ):
        with pytest.raises(InputError) as err:
            call()
        # the missing file first, then which product it belongs to and what to do
        assert str(err.value) == (
            f"{raster} does not exist: the SPOT DIMAP product {product} has its metadata "
            f"{product / 'METADATA.DIM'} but not this raster; copy the product's raster (as "
            "delivered: IMAGERY.TIF) back beside its METADATA.DIM, or give an image that exists"
        )


@pytest.mark.parametrize("given", ["METADATA.DIM", ""])
def test_the_metadata_or_folder_as_the_image_names_the_raster_it_lacks(product, given):
    with pytest.raises(
        InputError,
        match=f"SPOT DIMAP product without its raster: {product / 'IMAGERY.TIF'}, "
        "which its metadata names, does not exist",
    ):
        sensors.check_image(product / given)


def test_a_complete_product_and_a_plain_missing_file(small_scene, tmp_path):
    hrg = small_scene["images"]["HRG"]
    for path in (hrg["imagery"], hrg["metadata"]):
        assert sensors.check_image(path) is None  # raster and metadata are both there
    with pytest.raises(InputError, match="nothing.tif does not exist: check the path"):
        sensors.check_image(tmp_path / "nothing.tif")
