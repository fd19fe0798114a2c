"""pushbroom:orthorectify on the small simulated scene: the image's own orientation and a block's model,
a DEM in another CRS, the output file (type, nodata, CRS, overviews) equal to the engine's, errors, cancel."""

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProcessingFeedback

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.ortho import OrthoSettings, orthorectify


@pytest.fixture(scope="module")
def inputs(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("ortho_alg")
    utm_dem = str(folder / "dsm_utm.tif")
    gdal.Warp(utm_dem, small_scene["dsm"], dstSRS="EPSG:32616", xRes=5.0, yRes=5.0, resampleAlg="bilinear")
    return {"scene": small_scene, "dem": utm_dem, "folder": folder, "image": small_scene["images"]["HRG"]["imagery"]}


def run(parameters, feedback=None):
    return processing.run(
        "pushbroom:orthorectify",
        parameters,
        context=QgsProcessingContext(),
        feedback=feedback or QgsProcessingFeedback(),
    )


def test_image_with_its_own_orientation_equals_the_engine(pushbroom_provider, inputs, tmp_path, log):
    out = str(tmp_path / "ortho.tif")
    result = run({"IMAGE": inputs["image"], "DEM": inputs["dem"], "RESAMPLING": 1, "OUTPUT": out}, log)
    assert result["OUTPUT"] == out and 0 < result["BOUND"] <= 0.01
    assert any("achieved interpolation bound" in m for m in log.messages)
    ds = gdal.Open(out)
    assert ds.GetSpatialRef().GetAuthorityCode(None) == "32616"
    band = ds.GetRasterBand(1)
    assert band.DataType == gdal.GDT_Byte and band.GetNoDataValue() == 0 and band.GetOverviewCount() >= 1
    assert abs(ds.GetGeoTransform()[1] - 5.0) < 0.1  # HRG's 5 m ground sampling distance
    engine = orthorectify(
        inputs["image"],
        sensors.load(inputs["image"]),
        read_dem(inputs["dem"]),
        tmp_path / "engine.tif",
        settings=OrthoSettings(resampling_method="bicubic"),
    )
    assert engine.cells == result["CELLS"] > 300000
    np.testing.assert_array_equal(band.ReadAsArray(), gdal.Open(str(tmp_path / "engine.tif")).ReadAsArray())


def test_block_model_crs_and_cell_size(pushbroom_provider, inputs, tmp_path):
    path = str(tmp_path / "block.gpkg")
    Block.create(path, Block.open_images([inputs["image"]]), height=400.0)
    out = str(tmp_path / "ortho_block.tif")
    result = run(
        {
            "BLOCK": path,
            "IMAGE_NAME": "HRG",
            "DEM": inputs["scene"]["dsm"],
            "CRS": "EPSG:32617",
            "CELL_SIZE": 10.0,
            "OCCLUSION": True,
            "OUTPUT": out,
        }
    )
    ds = gdal.Open(out)
    assert ds.GetSpatialRef().GetAuthorityCode(None) == "32617" and ds.GetGeoTransform()[1] == 10.0
    assert result["CELLS"] > 80000
    with pytest.raises(
        QgsProcessingException,
        match=r"the block has no image 'HRS9': give the name of one of its "
        r"images \(HRG\)",
    ):
        run({"BLOCK": path, "IMAGE_NAME": "HRS9", "DEM": inputs["dem"], "OUTPUT": str(tmp_path / "x.tif")})


class CancelOnProgress(QgsProcessingFeedback):
    def __init__(self):
        super().__init__()
        self.progressChanged.connect(lambda _: self.cancel())


def test_cancel_and_a_dem_without_overlap(pushbroom_provider, inputs, tmp_path):
    out = tmp_path / "cancelled.tif"
    with pytest.raises(QgsProcessingException, match="cancelled"):
        run({"IMAGE": inputs["image"], "DEM": inputs["dem"], "OUTPUT": str(out)}, CancelOnProgress())
    assert not any(p.name.startswith((".cancelled", "cancelled")) for p in tmp_path.iterdir())
    far = str(tmp_path / "far.tif")
    gdal.Translate(far, inputs["dem"], outputBounds=[500000, 4000000, 501000, 3999000])
    with pytest.raises(QgsProcessingException, match="does not overlap"):
        run({"IMAGE": inputs["image"], "DEM": far, "OUTPUT": str(tmp_path / "far_ortho.tif")})


def test_a_true_orthoimage_with_its_occlusion_mask(pushbroom_provider, inputs, tmp_path):
    """HRS1 (20 degrees forward) on the true DSM: the occlusion mask beside the orthoimage, the occluded cells
    keeping the occluder's values where OCCLUSION is off."""
    out, mask = str(tmp_path / "true_ortho.tif"), str(tmp_path / "occlusions.tif")
    hrs1 = inputs["scene"]["images"]["HRS1"]["imagery"]
    result = run({"IMAGE": hrs1, "DEM": inputs["scene"]["dsm"], "OUTPUT": out, "OCCLUSIONS": mask})
    assert result["OCCLUSIONS"] == mask
    ds = gdal.Open(mask)
    band = ds.GetRasterBand(1)
    assert band.DataType == gdal.GDT_Byte and band.GetNoDataValue() == 255
    codes, values = band.ReadAsArray(), gdal.Open(out).ReadAsArray()
    band = ds = None
    assert (codes == 1).sum() > 1000 and set(np.unique(codes)) == {0, 1, 255}
    np.testing.assert_array_equal(codes == 255, values == 0)
    assert "OCCLUSIONS" not in run({"IMAGE": hrs1, "DEM": inputs["scene"]["dsm"], "OUTPUT": out})
