"""pushbroom:assessaccuracy on the simulated scene: a point cloud on the true DSM and a UTM DEM of the
DSM against the true DTM, with the simulator's classes; outputs (HTML report, CSV table, dh raster
styled with dh.qml) checked against the engine's statistics and GDAL."""

import csv
import pathlib
import re

import numpy as np
import pytest
from osgeo import gdal, ogr, osr
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProject, QgsRasterLayer

import pushbroom
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.simulation.terrain import CLASSES, FOREST
from pushbroom.algorithms.surface.geotiff import NODATA
from pushbroom.algorithms.surface.pointcloud import write_point_cloud
from tests.helpers.osr_oracle import utm

ALG = "pushbroom:assessaccuracy"
REPO = pathlib.Path(pushbroom.__file__).resolve().parent


@pytest.fixture(scope="module")
def inputs(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("assess")
    dsm = read_dem(small_scene["dsm"])
    rng = np.random.default_rng(2)
    lon0, lat0, lon1, lat1 = dsm.bounds
    lon, lat = rng.uniform(lon0 + 1e-3, lon1 - 1e-3, 3000), rng.uniform(lat0 + 1e-3, lat1 - 1e-3, 3000)
    cloud = folder / "points.las"
    write_point_cloud(cloud, lon, lat, dsm.height(lon, lat), {"group": rng.integers(1, 4, 3000).astype(np.uint8)})
    dem = folder / "dem.tif"
    gdal.Warp(
        str(dem), small_scene["dsm"], dstSRS="EPSG:32616", xRes=10, yRes=10, resampleAlg="average", dstNodata=-9999
    )
    return {"folder": folder, "points": str(cloud), "dem": str(dem), "lon": lon, "lat": lat}


def test_report_table_and_dh_raster(pushbroom_provider, small_scene, inputs, log, figures):
    out = inputs["folder"] / "run"
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    result = processing.run(
        ALG,
        {
            "REFERENCE": small_scene["dtm"],
            "POINTS": inputs["points"],
            "DEM": inputs["dem"],
            "CLASS_RASTER": small_scene["classes"],
            "SLOPE_THRESHOLD": 12.0,
            "REPORT": str(out / "report.html"),
            "TABLE": str(out / "stats.csv"),
            "DH": str(out / "dh.tif"),
        },
        context=context,
        feedback=log,
    )
    text = open(result["REPORT"], encoding="utf-8").read()
    assert not re.search(r"(src|href)\s*=\s*['\"](?!data:)", text)
    assert text.count("data:image/png;base64,") == 10 and "Zhang and Gruen 2004, Tables 2-3" in text
    assert "before and after co-registration" in text and "Nuth and Kääb 2011" in text
    assert CLASSES[FOREST] in text
    assert "slope &lt; 12 deg" in text and inputs["dem"] in text  # html-escaped "<"
    rows = list(csv.DictReader(open(result["TABLE"])))
    ds = gdal.Open(result["DH"])
    band = ds.GetRasterBand(1)
    dh = band.ReadAsArray().astype(float)
    assert band.GetNoDataValue() == NODATA and band.GetOverviewCount() > 0
    dh = dh[dh != NODATA]
    dem_all = next(r for r in rows if r["data"] == "DEM cells" and r["label"] == "dh")
    s = summarize(dh)
    figures.table("DEM (DSM averaged to 10 m) vs DTM (m)", [{"N": s.n, "mean": s.mean, "RMS": s.rms, "NMAD": s.nmad}])
    assert int(dem_all["n"]) == s.n
    np.testing.assert_allclose([float(dem_all[k]) for k in ("mean", "rms", "nmad")], [s.mean, s.rms, s.nmad], atol=1e-3)
    forest = next(
        r for r in rows if r["data"] == "object points" and r["table"] == "per class" and r["label"] == CLASSES[FOREST]
    )
    assert float(forest["mean"]) > 5.0
    assert any("per point group" in m and "Point group 3" in m for m in log.messages)
    layer = QgsRasterLayer(result["DH"], "dh")
    _, ok = layer.loadNamedStyle(str(REPO / "resources" / "styles" / "dh.qml"))
    renderer = layer.renderer()
    assert ok and renderer.type() == "singlebandpseudocolor"
    items = renderer.shader().rasterShaderFunction().colorRampItemList()
    values = [i.value for i in items]
    assert renderer.classificationMin() == -renderer.classificationMax() and values == [-v for v in values[::-1]]
    assert 0.0 in values


def test_bad_input_is_a_processing_error(pushbroom_provider, small_scene, inputs, tmp_path):
    with pytest.raises(QgsProcessingException, match="point cloud, a DEM or both"):
        processing.run(ALG, {"REFERENCE": small_scene["dtm"], "REPORT": str(tmp_path / "r.html")})
    ds = gdal.Open(small_scene["dtm"])
    gt = list(ds.GetGeoTransform())
    gt[0] += 3.0
    far = gdal.Translate(str(tmp_path / "far.tif"), ds)
    far.SetGeoTransform(gt)
    far = None
    with pytest.raises(QgsProcessingException, match="does not overlap"):
        processing.run(
            ALG, {"REFERENCE": str(tmp_path / "far.tif"), "DEM": inputs["dem"], "REPORT": str(tmp_path / "r.html")}
        )
    assert not (tmp_path / "r.html").exists()


def test_class_polygons(pushbroom_provider, small_scene, inputs, tmp_path):
    """Two UTM squares with a text class field: the per-class rows count the points inside each (OGR)."""
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(32616)
    path = str(tmp_path / "areas.gpkg")
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(path)
    layer = ds.CreateLayer("areas", srs, ogr.wkbPolygon)
    layer.CreateField(ogr.FieldDefn("landuse", ogr.OFTString))
    x, y = utm(inputs["lon"], inputs["lat"], 32616)
    xm, ym = float(np.median(x)), float(np.median(y))
    squares = {"west": (xm - 1000, ym - 1000, xm, ym + 1000), "east": (xm, ym - 1000, xm + 1000, ym + 1000)}
    for name, (x0, y0, x1, y1) in squares.items():
        feature = ogr.Feature(layer.GetLayerDefn())
        feature["landuse"] = name
        ring = f"{x0} {y0}, {x1} {y0}, {x1} {y1}, {x0} {y1}, {x0} {y0}"
        feature.SetGeometry(ogr.CreateGeometryFromWkt(f"POLYGON (({ring}))"))
        layer.CreateFeature(feature)
    ds = None
    result = processing.run(
        ALG,
        {
            "REFERENCE": small_scene["dtm"],
            "POINTS": inputs["points"],
            "CLASS_POLYGONS": path,
            "CLASS_FIELD": "landuse",
            "REPORT": str(tmp_path / "r.html"),
            "TABLE": str(tmp_path / "s.csv"),
        },
    )
    rows = {r["label"]: int(r["n"]) for r in csv.DictReader(open(result["TABLE"])) if r["table"] == "per class"}
    for name, (x0, y0, x1, y1) in squares.items():
        assert rows[name] == int(np.sum((x > x0) & (x < x1) & (y > y0) & (y < y1)))
