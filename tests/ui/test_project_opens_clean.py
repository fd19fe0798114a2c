"""A project whose layers carry every style of the plugin opens in the real QGIS desktop (Xvfb) with no
message in the message bar: no missing font, no unreadable layer (the demo project showed a warning bar for
the font "DejaVu LGC Sans"). The screenshot is kept beside the test's files."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
from osgeo import gdal, ogr, osr
from qgis.core import QgsApplication, QgsProject, QgsRasterLayer, QgsVectorLayer

import pushbroom
from pushbroom.plugin.styles import resolve_application_font

REPO = pathlib.Path(pushbroom.__file__).resolve().parent
SESSION = REPO / "tests" / "helpers" / "project_session.py"
STYLES = REPO / "resources" / "styles"


def make_data(folder):
    """A GeoPackage with a point, a line and a polygon layer with the fields the styles use, and a DEM."""
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(folder / "data.gpkg"))
    shapes = {
        "points": (ogr.wkbPoint25D, "POINT Z (-84.2 36.6 300)"),
        "vectors": (ogr.wkbLineString, "LINESTRING (-84.2 36.6, -84.19 36.61)"),
        "footprints": (ogr.wkbPolygon, "POLYGON ((-84.2 36.6, -84.1 36.6, -84.1 36.7, -84.2 36.6))"),
    }
    for name, (kind, wkt) in shapes.items():
        layer = ds.CreateLayer(name, srs, kind)
        for field, oft in [
            ("name", ogr.OFTString),
            ("role", ogr.OFTString),
            ("group", ogr.OFTInteger),
            ("residual_px", ogr.OFTReal),
            ("flagged", ogr.OFTInteger),
        ]:
            layer.CreateField(ogr.FieldDefn(field, oft))
        feat = ogr.Feature(layer.GetLayerDefn())
        feat["name"], feat["role"], feat["group"], feat["residual_px"] = "P1", "control", 3, 0.4
        feat.SetGeometry(ogr.CreateGeometryFromWkt(wkt))
        layer.CreateFeature(feat)
    ds = None
    dem = gdal.GetDriverByName("GTiff").Create(str(folder / "dem.tif"), 50, 50, 1, gdal.GDT_Float32)
    dem.SetGeoTransform((-84.2, 0.002, 0, 36.7, 0, -0.002))
    dem.SetProjection(srs.ExportToWkt())
    dem.GetRasterBand(1).WriteArray(np.linspace(200, 400, 2500, dtype=np.float32).reshape(50, 50))
    dem = None


def make_project(folder):
    resolve_application_font(QgsApplication.instance())  # as scripts/make_demo_project.py
    make_data(folder)
    project = QgsProject()
    for sub, qml in [
        ("points", "control_points.qml"),
        ("points", "points_by_group.qml"),
        ("vectors", "residual_vectors.qml"),
        ("footprints", "footprints.qml"),
    ]:
        layer = QgsVectorLayer(f"{folder / 'data.gpkg'}|layername={sub}", qml, "ogr")
        assert layer.isValid() and layer.loadNamedStyle(str(STYLES / qml))[1]
        project.addMapLayer(layer)
    for qml in ("dem.qml", "dh.qml"):
        layer = QgsRasterLayer(str(folder / "dem.tif"), qml, "gdal")
        assert layer.isValid() and layer.loadNamedStyle(str(STYLES / qml))[1]
        project.addMapLayer(layer)
    path = folder / "styled.qgz"
    assert project.write(str(path))
    return path


def open_in_desktop(project, folder):
    """Run the real QGIS desktop on `project` (tests/helpers/project_session.py); returns its result dict."""
    profiles = folder / "profiles"
    (profiles / "profiles" / "default").mkdir(parents=True)
    env = dict(
        os.environ,
        QT_QPA_PLATFORM="xcb",
        PUSHBROOM_PROJECT=str(project),
        PYTHONPATH=str(REPO),
        PUSHBROOM_RESULT=str(folder / "result.json"),
        PUSHBROOM_SCREENSHOT=str(folder / "screenshot.png"),
    )
    command = [
        "xvfb-run",
        "-a",
        "-s",
        "-screen 0 1600x1000x24",
        "/usr/bin/qgis.bin",
        "--profiles-path",
        str(profiles),
        "--nologo",
        "--noversioncheck",
        "--code",
        str(SESSION),
    ]
    log = subprocess.run(command, env=env, capture_output=True, text=True, timeout=180)
    assert (folder / "result.json").exists(), log.stdout[-3000:] + log.stderr[-3000:]
    return json.loads((folder / "result.json").read_text())


@pytest.mark.slow
def test_a_project_with_every_style_opens_without_a_message(qgis_app, tmp_path):
    result = open_in_desktop(make_project(tmp_path), tmp_path)
    assert result["errors"] == []
    assert result["messages"] == []  # no warning bar: fonts found, layers readable
    assert len(result["layers"]) == 6 and all(valid for _, valid in result["layers"])
    assert (tmp_path / "screenshot.png").stat().st_size > 10000
