"""pushbroom:interpolatedem through Processing: a LAS cloud with sigma_h, breaklines from a 3-D line
layer, EGM96 heights, the styled output, errors and cancelling."""

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import (
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeedback,
    QgsProcessingOutputLayerDefinition,
    QgsProject,
)

from pushbroom.algorithms.surface import pointcloud
from tests.helpers.roof_cloud import UTM31, roof_cloud


def run(parameters, context=None, feedback=None):
    return processing.run(
        "pushbroom:interpolatedem",
        parameters,
        context=context or QgsProcessingContext(),
        feedback=feedback or QgsProcessingFeedback(),
    )


def test_dem_with_breakline_precision_and_style(pushbroom_provider, tmp_path, log):
    las, lines, roof = roof_cloud(tmp_path)
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    out = QgsProcessingOutputLayerDefinition(str(tmp_path / "dem.tif"), QgsProject.instance())
    result = run(
        {
            "INPUT": las,
            "BREAKLINES": lines,
            "CELL": 5.0,
            "MAX_EDGE": 100.0,
            "BLUNDER_K": 0,
            "OUTPUT": out,
            "PRECISION": str(tmp_path / "sigma.tif"),
        },
        context,
        log,
    )
    ds = gdal.Open(result["OUTPUT"])
    assert ds.GetSpatialRef().GetAuthorityCode(None) == str(UTM31)  # the UTM zone of the points
    x0, cell, _, y0, _, _ = ds.GetGeoTransform()
    dem = ds.GetRasterBand(1).ReadAsArray().astype(float)
    ok = dem != ds.GetRasterBand(1).GetNoDataValue()
    cx = x0 + (np.arange(dem.shape[1]) + 0.5) * cell
    assert ok.mean() > 0.95
    np.testing.assert_allclose(dem[ok], np.broadcast_to(roof(cx), dem.shape)[ok], atol=1e-3)  # LAS mm
    precision = gdal.Open(result["PRECISION"])  # keep the dataset alive while its band is read
    sigma = precision.GetRasterBand(1).ReadAsArray()
    np.testing.assert_allclose(sigma[ok], 0.4, atol=1e-6)
    assert result["REMOVED"] == 0 and result["POINTS"] > 4000  # breakline vertices added
    assert any("0 blunders removed" in m and "breakline vertices" in m for m in log.messages)
    assert context.willLoadLayerOnCompletion(result["OUTPUT"])
    assert context.layerToLoadOnCompletionDetails(result["OUTPUT"]).postProcessor() is not None


def test_egm96_heights_in_a_given_crs(pushbroom_provider, tmp_path):
    las, _, _ = roof_cloud(tmp_path)
    ellipsoidal = run({"INPUT": las, "CRS": "EPSG:2154", "CELL": 20.0, "OUTPUT": str(tmp_path / "h.tif")})
    geoid = run({"INPUT": las, "CRS": "EPSG:2154", "CELL": 20.0, "DATUM": 1, "OUTPUT": str(tmp_path / "H.tif")})
    h, big_h = (gdal.Open(r["OUTPUT"]) for r in (ellipsoidal, geoid))
    assert big_h.GetSpatialRef().GetAuthorityCode(None) == "2154"
    diff = h.ReadAsArray().astype(float) - big_h.ReadAsArray()
    ok = h.ReadAsArray() != -32767
    assert 48 < diff[ok].mean() < 52 and np.ptp(diff[ok]) < 0.05  # EGM96 N near Mont Ventoux ~ 50 m
    assert "EGM96" in big_h.GetMetadata()["HEIGHT_DATUM"]


def test_per_cell_dem_with_counts(pushbroom_provider, tmp_path):
    las, lines, roof = roof_cloud(tmp_path, n=40000)
    result = run(
        {
            "INPUT": las,
            "CELL": 20.0,
            "METHOD": 1,
            "OUTPUT": str(tmp_path / "cells.tif"),
            "PRECISION": str(tmp_path / "se.tif"),
            "COUNT": str(tmp_path / "n.tif"),
        }
    )
    dem, count, se = (gdal.Open(result[k]) for k in ("OUTPUT", "COUNT", "PRECISION"))
    n = count.ReadAsArray()
    assert n.sum() == result["POINTS"] == 40000 - result["REMOVED"] and 0.9 * 2500 < (n > 0).sum() <= 2601
    x0, cell, _, _, _, _ = dem.GetGeoTransform()
    h = dem.ReadAsArray().astype(float)
    ok = n > 0
    ridge = np.abs(x0 + (np.arange(h.shape[1]) + 0.5) * cell - 650_500) < cell  # the ridge's own cells
    truth = np.broadcast_to(roof(x0 + (np.arange(h.shape[1]) + 0.5) * cell), h.shape)
    dh = np.abs(h - truth)[ok & ~ridge]  # a cell's median on a 0.5 slope: within its +-5 m, near its centre
    assert dh.max() < 5.0 and np.median(dh) < 1.0
    # every point has sigma_h 0.4 m: the cell's precision is their RMS, whatever its count (cell_dem.py)
    assert np.allclose(se.ReadAsArray()[ok & (n >= 1)], 0.4, rtol=1e-4)
    assert dem.GetMetadata()["METHOD"] == "per-cell median"
    with pytest.raises(QgsProcessingException, match="per-cell method"):
        run({"INPUT": las, "CELL": 20.0, "OUTPUT": str(tmp_path / "tin.tif"), "COUNT": str(tmp_path / "n2.tif")})
    with pytest.raises(QgsProcessingException, match="breaklines"):
        run({"INPUT": las, "CELL": 20.0, "METHOD": 1, "BREAKLINES": lines, "OUTPUT": str(tmp_path / "c2.tif")})


def test_errors_and_cancel(pushbroom_provider, tmp_path):
    las, _, _ = roof_cloud(tmp_path)
    few = pointcloud.write_point_cloud(tmp_path / "two.gpkg", [5.0, 5.1], [44.0, 44.1], [1.0, 2.0])[0]
    with pytest.raises(QgsProcessingException, match="at least 3 points"):
        run({"INPUT": few, "OUTPUT": str(tmp_path / "a.tif")})
    cancelled = QgsProcessingFeedback()
    cancelled.cancel()
    with pytest.raises(QgsProcessingException, match="cancel"):
        run({"INPUT": las, "OUTPUT": str(tmp_path / "b.tif")}, feedback=cancelled)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cloud.las", "lines.gpkg", "two.gpkg"]


def test_per_cell_dem_fills_its_gaps_into_a_mask(pushbroom_provider, tmp_path):
    las, _, _ = roof_cloud(tmp_path, n=3000)  # about one point per cell of 20 m: gaps between them
    plain = run({"INPUT": las, "CELL": 20.0, "METHOD": 1, "RADIUS": 0, "OUTPUT": str(tmp_path / "plain.tif")})
    result = run(
        {
            "INPUT": las,
            "CELL": 20.0,
            "METHOD": 1,
            "RADIUS": 0,
            "FILL": 3,
            "OUTPUT": str(tmp_path / "filled.tif"),
            "MASK": str(tmp_path / "mask.tif"),
        }
    )
    near = run(
        {
            "INPUT": las,
            "CELL": 20.0,
            "METHOD": 1,
            "OUTPUT": str(tmp_path / "near.tif"),
            "MASK": str(tmp_path / "near_mask.tif"),
        }
    )  # RADIUS 1 by default
    ds = gdal.Open(plain["OUTPUT"])
    before, nodata = ds.ReadAsArray(), ds.GetRasterBand(1).GetNoDataValue()
    after = gdal.Open(result["OUTPUT"]).ReadAsArray()
    mask = gdal.Open(result["MASK"]).ReadAsArray()
    gaps = before == nodata
    assert result["FILLED"] == (mask == 1).sum() == (gaps & (after != nodata)).sum() > 0.1 * gaps.sum()
    assert np.array_equal(mask == 0, ~gaps) and np.array_equal(after[~gaps], before[~gaps])
    assert "MASK" not in plain
    # radius 1: the empty cells next to points take theirs, flagged 2; the others are as before
    around = gdal.Open(near["MASK"]).ReadAsArray()
    heights = gdal.Open(near["OUTPUT"]).ReadAsArray()
    assert np.array_equal(around == 0, ~gaps) and np.array_equal(heights[~gaps], before[~gaps])
    assert near["FILLED"] == 0 and (around == 2).sum() > 0.5 * gaps.sum() and (heights[around == 2] != nodata).all()
