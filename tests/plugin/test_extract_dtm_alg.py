"""pushbroom:extractdtm on the simulated scene's true DSM (UTM, 5 m): the DTM, the DHM and the mask written and
loaded styled, the DTM below the DSM where the town stands; a DSM in degrees refused with what to do."""

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProcessingOutputLayerDefinition, QgsProject

from pushbroom.algorithms.simulation.terrain import CITY


def test_dtm_dhm_and_mask_loaded(pushbroom_provider, small_scene, tmp_path, log):
    dsm, classes = str(tmp_path / "dsm.tif"), str(tmp_path / "classes.tif")
    for source, path, resampling in ((small_scene["dsm"], dsm, "bilinear"), (small_scene["classes"], classes, "near")):
        gdal.Warp(path, source, dstSRS="EPSG:32616", xRes=5, yRes=5, resampleAlg=resampling, errorThreshold=0)
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    project = QgsProject.instance()
    result = processing.run(
        "pushbroom:extractdtm",
        {
            "DSM": dsm,
            "OUTPUT": QgsProcessingOutputLayerDefinition(str(tmp_path / "dtm.tif"), project),
            "DHM": QgsProcessingOutputLayerDefinition(str(tmp_path / "dhm.tif"), project),
            "MASK": str(tmp_path / "mask.tif"),
        },
        context=context,
        feedback=log,
    )
    assert any("not safe in threads, run on local worker processes" in m for m in log.messages)
    datasets = {key: gdal.Open(result[key]) for key in ("OUTPUT", "DHM", "MASK")}  # alive while read
    dhm = datasets["DHM"].GetRasterBand(1).ReadAsArray()
    classes_ds = gdal.Open(classes)
    town = classes_ds.GetRasterBand(1).ReadAsArray() == CITY
    valid = dhm > -1000
    # the town's lots hold buildings and streets: its heights above the ground average metres, the rest's none
    assert np.mean(dhm[town & valid]) > 2.0 and abs(np.median(dhm[~town & valid])) < 0.5
    assert datasets["MASK"].GetRasterBand(1).DataType == gdal.GDT_Byte
    for key in ("OUTPUT", "DHM"):
        assert context.willLoadLayerOnCompletion(result[key])
        assert context.layerToLoadOnCompletionDetails(result[key]).postProcessor() is not None


def test_a_dsm_in_degrees_is_refused(pushbroom_provider, small_scene, tmp_path):
    with pytest.raises(QgsProcessingException, match="warp it to a projected CRS"):
        processing.run("pushbroom:extractdtm", {"DSM": small_scene["dsm"], "OUTPUT": str(tmp_path / "x.tif")})
