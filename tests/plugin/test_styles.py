"""The QML styles name no font QGIS may lack: a label font missing on the system makes QGIS show a warning
bar when a project with the layer opens (the demo project did, with "DejaVu LGC Sans")."""

import pathlib
import xml.etree.ElementTree as ET

import pytest
from qgis.core import QgsVectorLayer
from qgis.PyQt.QtGui import QFontDatabase

import pushbroom

STYLES = sorted((pathlib.Path(pushbroom.__file__).resolve().parent / "resources" / "styles").glob("*.qml"))
LAYERS = {
    "control_points.qml": "PointZ?field=name:string&field=residual_px:double",
    "footprints.qml": "Polygon?field=name:string",
    "residual_vectors.qml": "LineString?field=name:string",
}


@pytest.mark.parametrize("style", STYLES, ids=lambda p: p.name)
def test_label_fonts_are_the_applications_or_installed(qgis_app, style):
    families = set(QFontDatabase().families())
    named = [e.get("fontFamily") for e in ET.parse(style).iter("text-style") if e.get("fontFamily")]
    assert all(f in families for f in named), named  # no fontFamily: QGIS uses the application's font


@pytest.mark.parametrize("name", sorted(LAYERS))
def test_labelled_styles_load_with_their_font_found(qgis_app, name):
    layer = QgsVectorLayer(LAYERS[name] + "&crs=EPSG:4326", name, "memory")
    message, ok = layer.loadNamedStyle(str(STYLES[[s.name for s in STYLES].index(name)]))
    assert ok, message
    assert layer.labelsEnabled() and layer.labeling().settings().format().fontFound()


def test_the_occlusion_mask_style_paints_the_occluded_cells(qgis_app, tmp_path):
    """occlusions.qml on a mask of orthorectify's codes: a paletted renderer, occluded cells opaque, seen ones clear."""
    import numpy as np
    from osgeo import gdal
    from qgis.core import QgsRasterLayer

    path = str(tmp_path / "mask.tif")
    ds = gdal.GetDriverByName("GTiff").Create(path, 4, 4, 1, gdal.GDT_Byte)
    ds.GetRasterBand(1).WriteArray(np.array([[0, 1, 255, 0]] * 4, np.uint8))
    ds.GetRasterBand(1).SetNoDataValue(255)
    ds = None
    layer = QgsRasterLayer(path, "mask")
    message, ok = layer.loadNamedStyle(str(STYLES[[s.name for s in STYLES].index("occlusions.qml")]))
    assert ok, message
    renderer = layer.renderer()
    assert renderer.type() == "paletted"
    colours = {c.value: c.color.alpha() for c in renderer.classes()}
    assert colours == {0.0: 0, 1.0: 255}
