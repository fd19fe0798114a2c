"""Parameter checks in Pushbroom's words (issue 36): every number parameter states its range in its help, and
a value out of it, or NaN, is refused naming the parameter and the range (before: QGIS's "Incorrect
parameter value for CELL", and NaN ran); a raster QGIS cannot load is named with why. Under qgis_process no
GDAL line comes before Pushbroom's message and loading a raw RPC image prints no "Creating Warped VRT"."""

import math
import shutil
import subprocess

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingException, QgsProcessingParameterNumber

from pushbroom.algorithms.block import Block
from pushbroom.plugin import gdal_messages
from pushbroom.plugin.algorithms import algorithm_classes
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env
from tests.helpers.rpc_synthetic import raster_with_rpc


def number_parameters(provider):
    for cls in algorithm_classes():
        for definition in provider.algorithm(cls.NAME).parameterDefinitions():
            if isinstance(definition, QgsProcessingParameterNumber):
                yield cls.NAME, definition


def test_every_range_is_stated_in_the_help(pushbroom_provider):
    bounded = 0
    for name, definition in number_parameters(pushbroom_provider):
        low, high = definition.minimum(), definition.maximum()
        for bound in (low, high):
            if math.isfinite(bound) and abs(bound) < 1e300:  # QGIS's "no bound" is +-DBL_MAX
                assert f"{bound:g}" in definition.help(), (name, definition.name(), definition.help())
                bounded += 1
    assert bounded > 40  # the steps have some 60 bounded number parameters: the check saw them


def test_a_number_out_of_range_or_nan_is_refused_with_the_range(pushbroom_provider, tmp_path):
    cell = pushbroom_provider.algorithm("selecttiepoints").parameterDefinition("CELL")
    for value, shown in (
        (0.0, "0 is out of range"),
        (float("nan"), "nan is not a number"),
        ("nan", "nan is not a number"),
        ("ten", "'ten' is not a number"),
    ):
        with pytest.raises(QgsProcessingException) as err:
            processing.run("pushbroom:selecttiepoints", {"BLOCK": str(tmp_path / "b.gpkg"), "CELL": value})
        assert f"CELL: {shown}: give a number of at least {cell.minimum():g}" in str(err.value)
    radius = pushbroom_provider.algorithm("interpolatedem").parameterDefinition("RADIUS")
    with pytest.raises(
        QgsProcessingException,
        match=rf"RADIUS: 9 is out of range: give a whole number from 0 to "
        rf"{radius.maximum():g}",
    ):
        processing.run(
            "pushbroom:interpolatedem",
            {"INPUT": str(tmp_path / "c.las"), "RADIUS": 9, "METHOD": 1, "OUTPUT": str(tmp_path / "d.tif")},
        )


def test_a_dimap_product_without_its_raster_is_named(pushbroom_provider, small_scene, tmp_path):
    """Before: "Could not load source layer for IMAGE: .../METADATA.DIM not found", of a file that exists."""
    product = tmp_path / "HRG"
    shutil.copy(small_scene["images"]["HRG"]["metadata"], product.mkdir() or product / "METADATA.DIM")
    with pytest.raises(QgsProcessingException) as err:
        processing.run(
            "pushbroom:orthorectify",
            {"IMAGE": str(product / "METADATA.DIM"), "DEM": small_scene["dsm"], "OUTPUT": str(tmp_path / "o.tif")},
        )
    assert (
        f"IMAGE: {product / 'METADATA.DIM'} is a SPOT DIMAP product without its raster: "
        f"{product / 'IMAGERY.TIF'}, which its metadata names, does not exist"
    ) in str(err.value)


def test_gdal_failures_raised_as_exceptions_are_not_printed(capsys, tmp_path):
    """qgis_process's GDAL handler: a failure that GDAL's bindings raise (exceptions on, as the engine has them)
    is the caller's to report; one reported from elsewhere (QGIS's C++ code: here called directly) is printed,
    as are warnings."""
    garbage = tmp_path / "g.tif"
    garbage.write_text("no raster")
    gdal.UseExceptions()
    gdal.PushErrorHandler(gdal_messages._console)
    try:
        with pytest.raises(RuntimeError, match="not recognized"):
            gdal.Open(str(garbage))
        assert capsys.readouterr().err == ""  # raised, not printed
        gdal_messages._console(gdal.CE_Failure, 4, "a failure met in QGIS")
        gdal_messages._console(gdal.CE_Failure, 1, gdal_messages.NO_GEOREFERENCING + " (level-1A)")
        gdal.Error(gdal.CE_Warning, 1, "a warning")
        assert capsys.readouterr().err == "ERROR 4: a failure met in QGIS\nWarning 1: a warning\n"
    finally:
        gdal.PopErrorHandler()


@pytest.fixture(scope="module")
def console(tmp_path_factory):
    """Run qgis_process with the plugin; returns the CompletedProcess (text)."""
    env = qgis_process_env(tmp_path_factory.mktemp("qgis-profile"))
    return lambda *args: subprocess.run(
        [QGIS_PROCESS, "run", *args], env=env, capture_output=True, text=True, timeout=600
    )


def test_a_raw_rpc_image_loads_without_noise(console, tmp_path):
    """QGIS warps a raw RPC image to load it as a raster parameter and says "Creating Warped VRT." each time."""
    image = raster_with_rpc(tmp_path / "rpc.tif")
    dem = gdal.GetDriverByName("GTiff").Create(str(tmp_path / "dem.tif"), 20, 20, 1, gdal.GDT_Float32)
    dem.SetGeoTransform((5.1, 0.01, 0.0, 44.2, 0.0, -0.01))
    dem.SetProjection("EPSG:4326")
    dem.GetRasterBand(1).WriteArray(np.full((20, 20), 500.0, np.float32))
    dem = None
    result = console(
        "pushbroom:orthorectify",
        "--",
        f"IMAGE={image}",
        f"DEM={tmp_path / 'dem.tif'}",
        "CRS=EPSG:999999",
        f"OUTPUT={tmp_path / 'o.tif'}",
    )
    assert result.returncode == 1
    assert "Warped VRT" not in result.stderr + result.stdout  # the raster loaded: no note of it
    assert result.stderr.count("'EPSG:999999' is not a coordinate reference system QGIS knows") == 1


def test_no_gdal_line_before_pushbroom_message(console, small_scene, tmp_path):
    """A block whose image was overwritten since: before, the console handler printed "ERROR 4: `...IMAGERY.TIF'
    not recognized as a supported file format." and then Pushbroom's message saying the same."""
    shutil.copytree(small_scene["images"]["HRG"]["imagery"].rsplit("/", 1)[0], tmp_path / "HRG")
    image = tmp_path / "HRG" / "IMAGERY.TIF"
    Block.create(str(tmp_path / "b.gpkg"), Block.open_images([str(image)]), height=300.0)
    image.write_text("no longer an image")
    result = console(
        "pushbroom:orthorectify",
        "--",
        f"BLOCK={tmp_path / 'b.gpkg'}",
        "IMAGE_NAME=HRG",
        f"DEM={small_scene['dsm']}",
        f"OUTPUT={tmp_path / 'o.tif'}",
    )
    assert result.returncode == 1
    assert result.stderr.count(f"cannot open the image {image}") == 1
    assert "ERROR 4" not in result.stderr  # GDAL's own line of the same failure
