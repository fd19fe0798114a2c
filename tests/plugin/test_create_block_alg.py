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
    gdal.GetDriverByName("GTiff").Create(str(folder / "IMAGERY.TIF"), 12000, 12000, 1, gdal.GDT_Byte,
                                         ["SPARSE_OK=TRUE", "TILED=YES"])
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


@pytest.mark.slow
def test_createblock_with_qgis_process(qgis_process, product, tmp_path):
    listing = qgis_process("list")
    ids = {a for p in listing["providers"].values() for a in p["algorithms"]}
    assert "pushbroom:createblock" in ids
    out = tmp_path / "block.gpkg"
    result = qgis_process("run", "pushbroom:createblock", "--", f"IMAGES={product}", f"OUTPUT={out}")
    assert result["results"]["OUTPUT"] == str(out)
    assert out.exists()
