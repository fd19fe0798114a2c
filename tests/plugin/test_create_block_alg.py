"""pushbroom:createblock through Processing and through qgis_process."""

import shutil

import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingException, QgsVectorLayer


@pytest.fixture
def product(spot5_dim, tmp_path):
    """A SPOT 5 product folder: the real metadata and a blank (sparse) 12000 x 12000 IMAGERY.TIF."""
    folder = tmp_path / "HRG1"
    folder.mkdir()
    shutil.copy(spot5_dim, folder / "METADATA.DIM")
    gdal.GetDriverByName("GTiff").Create(
        str(folder / "IMAGERY.TIF"), 12000, 12000, 1, gdal.GDT_Byte, ["SPARSE_OK=TRUE", "TILED=YES"]
    )
    return folder / "IMAGERY.TIF"


def test_createblock_in_processing(pushbroom_provider, product, tmp_path):
    out = tmp_path / "block.gpkg"
    result = processing.run("pushbroom:createblock", {"IMAGES": [str(product)], "OUTPUT": str(out)})
    assert result["OUTPUT"] == str(out)
    layer = QgsVectorLayer(result["FOOTPRINTS"], "fp", "ogr")
    assert layer.isValid() and layer.featureCount() == 1
    assert layer.crs().authid() == "EPSG:4326"
    with pytest.raises(QgsProcessingException, match="overwrite"):
        processing.run("pushbroom:createblock", {"IMAGES": [str(product)], "OUTPUT": str(out)})


@pytest.mark.parametrize("height", [60000.0, -20000.0])
def test_a_mean_height_off_the_earth_is_refused(pushbroom_provider, product, tmp_path, height):
    # issue 36: a block made at 60 km (a flying height? feet?) put its footprints and height range there
    with pytest.raises(
        QgsProcessingException,
        match=rf"the mean terrain height \(HEIGHT\) of {height:g} m lies "
        r"outside the heights of terrain on Earth \(-500 \.\. 9000 m",
    ):
        processing.run(
            "pushbroom:createblock",
            {"IMAGES": [str(product)], "HEIGHT": height, "OUTPUT": str(tmp_path / "block.gpkg")},
        )
    assert not (tmp_path / "block.gpkg").exists()


def test_the_same_image_twice_is_refused(pushbroom_provider, product, tmp_path):
    link = tmp_path / "link.tif"
    link.symlink_to(product)
    with pytest.raises(QgsProcessingException, match=r"images 1 and 2 .* are one file: a block holds each image once"):
        processing.run(
            "pushbroom:createblock", {"IMAGES": [str(product), str(link)], "OUTPUT": str(tmp_path / "block.gpkg")}
        )
    assert not (tmp_path / "block.gpkg").exists()


@pytest.mark.slow
def test_createblock_with_qgis_process(qgis_process, product, tmp_path):
    listing = qgis_process("list")
    ids = {a for p in listing["providers"].values() for a in p["algorithms"]}
    assert "pushbroom:createblock" in ids
    out = tmp_path / "block.gpkg"
    result = qgis_process("run", "pushbroom:createblock", "--", f"IMAGES={product}", f"OUTPUT={out}")
    assert result["results"]["OUTPUT"] == str(out)
    assert out.exists()


def test_createblock_without_dem_and_height_finds_the_terrain(pushbroom_provider, ventoux_pair, tmp_path):
    from pushbroom.algorithms.block import Block

    given = tmp_path / "given.gpkg"
    processing.run(
        "pushbroom:createblock", {"IMAGES": [str(p) for p in ventoux_pair], "HEIGHT": 0.0, "OUTPUT": str(given)}
    )
    assert Block(str(given)).height_range() == (-500.0, 500.0)
    found = tmp_path / "found.gpkg"
    processing.run("pushbroom:createblock", {"IMAGES": [str(p) for p in ventoux_pair], "OUTPUT": str(found)})
    h_min, h_max = Block(str(found)).height_range()
    # the terrain under the pair: 512-568 m (tests/real/test_height_search_real.py), the RPC valid for 190-1960 m
    assert 190.0 < h_min < 512.0 and 568.0 < h_max < 1000.0, (h_min, h_max)
    assert "points matched over 190 to 1960 m" in Block(str(found)).info()["height_search"]
