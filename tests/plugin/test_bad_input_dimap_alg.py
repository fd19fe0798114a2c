"""pushbroom:createblock on a SPOT DIMAP product without its raster (issue 19): in Processing and through
qgis_process the message names the missing IMAGERY.TIF instead of 'Incorrect parameter value for IMAGES'."""

import pytest

from tests.helpers.bad_inputs import processing_error, product_without_raster


@pytest.fixture
def product(small_scene, tmp_path):
    return product_without_raster(small_scene, tmp_path)


def test_createblock_names_the_missing_raster(pushbroom_provider, product, small_scene, tmp_path):
    raster = product / "IMAGERY.TIF"
    message = processing_error(
        "pushbroom:createblock",
        {"IMAGES": [small_scene["images"]["HRS1"]["imagery"], str(raster)], "OUTPUT": str(tmp_path / "b.gpkg")},
    )
    # the missing raster, the product it belongs to, and no QGIS parameter text
    assert f"{raster} does not exist: the SPOT DIMAP product {product} has its metadata" in message
    assert "Incorrect parameter value" not in message  # QGIS's text replaced, not appended to
    message = processing_error(
        "pushbroom:createblock", {"IMAGES": [str(product / "METADATA.DIM")], "OUTPUT": str(tmp_path / "b.gpkg")}
    )
    # the metadata given as the image: the raster it names (after Processing's 'Unable to execute algorithm')
    assert message.endswith(
        f"{product / 'METADATA.DIM'} is a SPOT DIMAP product without its raster: {raster}, "
        "which its metadata names, does not exist; copy the product's raster back beside its "
        "METADATA.DIM, or give an image that exists"
    )
    assert not (tmp_path / "b.gpkg").exists()  # refused before anything was written


@pytest.mark.slow
def test_createblock_with_qgis_process_names_the_missing_raster(qgis_process, product, tmp_path):
    with pytest.raises(RuntimeError) as err:
        qgis_process(
            "run", "pushbroom:createblock", "--", f"IMAGES={product / 'IMAGERY.TIF'}", f"OUTPUT={tmp_path / 'b.gpkg'}"
        )
    # what the user reads on the terminal: the missing raster and what to do, no traceback
    assert f"{product / 'IMAGERY.TIF'} does not exist: the SPOT DIMAP product {product}" in str(err.value)
    assert "copy the product's raster" in str(err.value) and "Traceback" not in str(err.value)  # and what to do
