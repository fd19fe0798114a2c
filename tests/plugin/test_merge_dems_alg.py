"""pushbroom:mergedems on the simulated scene (issue 40): two overlapping DSMs made from the simulator's true DSM
(warped to UTM, exact), the second moved 4 m west and 1.5 m up with noise, each with its precision raster: merged
with co-registration, the merged DEM lies on the truth, with no seam where the second DSM begins, and the outputs
are loaded styled."""

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import (
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingOutputLayerDefinition,
    QgsProject,
)
from scipy import ndimage

from pushbroom.algorithms.surface.geotiff import write_float_raster
from tests.helpers.dem_shift import warped_dsm

CELL = 10.0


@pytest.fixture(scope="module")
def pairs(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("mergedems")
    h, gt, srs = warped_dsm(small_scene["dsm"], folder / "truth.tif", CELL, 32616)
    rows, cols = h.shape
    half = cols // 2
    rng = np.random.default_rng(3)
    west = h[:, : half + 60] + rng.normal(0, 0.3, (rows, half + 60))
    east = h[:, half - 60 :] + 1.5 + rng.normal(0, 0.5, (rows, cols - half + 60))
    east_gt = (gt[0] + (half - 60) * CELL - 4.0, CELL, 0, gt[3], 0, -CELL)  # its grid 4 m west of its heights
    out = {"folder": folder, "truth": h, "overlap": (half - 60, half + 60)}
    out["west"] = write_float_raster(str(folder / "west.tif"), west, gt, srs)
    out["east"] = write_float_raster(str(folder / "east.tif"), east, east_gt, srs)
    out["sw"] = write_float_raster(str(folder / "sw.tif"), np.full(west.shape, 0.3), gt, srs)
    out["se"] = write_float_raster(str(folder / "se.tif"), np.full(east.shape, 0.5), east_gt, srs)
    return out


def merged_dh(pairs, name, context=None, feedback=None, **settings):
    """(merged DEM - truth, count, the run's result) of a merge of the two DSMs with `settings`."""
    folder = pairs["folder"]
    result = processing.run(
        "pushbroom:mergedems",
        {
            "DEMS": [pairs["west"], pairs["east"]],
            "PRECISIONS": [pairs["sw"], pairs["se"]],
            "OUTPUT": QgsProcessingOutputLayerDefinition(str(folder / f"{name}.tif"), QgsProject.instance()),
            "COUNT": str(folder / f"{name}-count.tif"),
            **settings,
        },
        context=context or QgsProcessingContext(),
        feedback=feedback,
    )
    merged_ds, count_ds = gdal.Open(result["OUTPUT"]), gdal.Open(result["COUNT"])  # alive while their bands are read
    rows, cols = pairs["truth"].shape
    merged = merged_ds.GetRasterBand(1).ReadAsArray().astype(float)[:rows, :cols]
    count = count_ds.GetRasterBand(1).ReadAsArray()[:rows, :cols]
    return merged - pairs["truth"], count, result


def seam(dh, edge):
    """The largest step of dh's column means (over the rows) within 15 columns of `edge`, and elsewhere inside the
    overlap's columns and the east DSM's own."""
    profile = np.nanmean(dh[20:-20], axis=0)
    steps = np.abs(np.diff(profile))
    near = steps[edge - 15 : edge + 15].max()
    away = np.concatenate([steps[edge - 100 : edge - 20], steps[edge + 20 : edge + 100]]).max()
    return near, away


def test_merged_on_the_truth_without_a_seam(pushbroom_provider, pairs, log, figures):
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    dh, count, result = merged_dh(pairs, "merged", context, log)
    assert any("east.tif: co-registered, east +4.0" in m for m in log.messages), log.messages
    a, b = pairs["overlap"]
    ok = np.isfinite(pairs["truth"])
    inner = ndimage.binary_erosion(ok, iterations=3)  # the truth's nodata edges are both DSMs' edges too
    assert (count[:, a + 12 : b - 12][inner[:, a + 12 : b - 12]] == 2).all()
    assert (count[:, : a - 2][inner[:, : a - 2]] == 1).all()
    # the west DSM ends at column b: its heights and the east DSM's, 1.5 m higher before co-registration
    plain, _, _ = merged_dh(pairs, "plain", COREGISTER=False)
    sharp, _, _ = merged_dh(pairs, "sharp", COREGISTER=False, BLEND=0)
    rows = []
    for label, values in (("co-registered", dh), ("not co-registered", plain), ("not co-registered, no blend", sharp)):
        near, away = seam(values, b)
        rows.append(
            {"merge": label, "median dh": float(np.nanmedian(values)), "step at the edge": near, "elsewhere": away}
        )
    figures.table("Two simulated DSMs merged: the largest step of dh's column means (m) at the west DSM's edge", rows)
    assert abs(rows[0]["median dh"]) < 0.05 and rows[0]["step at the edge"] < 1.5 * rows[0]["elsewhere"]
    # the blend spreads the 1.1 m the weights change by over its 10 cells (0.15 m a column at most, on flat ground,
    # beside the column means' own 0.14 m); without it, one step
    assert rows[1]["step at the edge"] < 0.3 < 0.8 < rows[2]["step at the edge"]
    assert context.willLoadLayerOnCompletion(result["OUTPUT"])
    assert context.layerToLoadOnCompletionDetails(result["OUTPUT"]).postProcessor() is not None


def test_a_precision_output_without_precision_rasters_is_refused(pushbroom_provider, pairs):
    with pytest.raises(QgsProcessingException, match="needs the DEMs' precision rasters"):
        processing.run(
            "pushbroom:mergedems",
            {
                "DEMS": [pairs["west"], pairs["east"]],
                "OUTPUT": str(pairs["folder"] / "m2.tif"),
                "PRECISION": str(pairs["folder"] / "p2.tif"),
            },
        )
