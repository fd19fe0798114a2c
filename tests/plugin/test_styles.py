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
