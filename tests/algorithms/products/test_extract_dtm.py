"""products.extract_dtm (CNES Bulldozer, tile by tile) on the simulated scene's true DSM (UTM, 5 m), against the
simulator's true DTM by class: the DTM lies on the ground on open land and takes off most of the forest and the
town; the DHM is the DSM less the DTM; tiles agree with one run over the whole DSM; the DSM's nodata stays nodata;
a DSM in degrees is refused."""

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.products.extract_dtm import DtmOutputs, DtmParams, axis_tiles, extract_dtm, window_of
from pushbroom.algorithms.simulation.terrain import BARE, CITY, CLASSES, CROPS, FOREST
from tests.helpers.dem_cloud import read_raster
from tests.helpers.dem_shift import warped_dsm


def warped(source, path, resampling, bounds=None):
    """`source` warped to UTM 16N at 5 m (exact), over `bounds` where given; its values with NaN for nodata."""
    return warped_dsm(source, path, 5.0, 32616, bounds, resampling)[0]


@pytest.fixture(scope="module")
def scene(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("dtm")
    dsm = str(folder / "dsm.tif")
    dsm_values = warped(small_scene["dsm"], dsm, "bilinear")
    ds = gdal.Open(dsm)
    gt = ds.GetGeoTransform()
    bounds = (gt[0], gt[3] + ds.RasterYSize * gt[5], gt[0] + ds.RasterXSize * gt[1], gt[3])
    return {
        "folder": folder,
        "dsm": dsm,
        "dsm_values": dsm_values,
        "dtm": warped(small_scene["dtm"], folder / "dtm.tif", "bilinear", bounds),
        "classes": warped(small_scene["classes"], folder / "classes.tif", "near", bounds),
    }


def read(path):
    return read_raster(path)[0]


@pytest.fixture(scope="module")
def extracted(scene):
    folder = scene["folder"]
    out = DtmOutputs(str(folder / "dtm_out.tif"), str(folder / "dhm.tif"), str(folder / "mask.tif"))
    extract_dtm(scene["dsm"], out, DtmParams(execution=Execution("threads", 2)))
    return {key: read(path) for key, path in zip(("dtm", "dhm", "mask"), (out.dtm, out.dhm, out.mask))}


def test_the_dtm_by_class_against_the_truth(scene, extracted, figures):
    dtm, dsm, truth, classes = extracted["dtm"], scene["dsm_values"], scene["dtm"], scene["classes"]
    rows = []
    rms = {}
    for code in (BARE, CROPS, FOREST, CITY):
        cells = (classes == code) & np.isfinite(dtm) & np.isfinite(truth)
        rms[code] = (np.sqrt(np.mean((dtm - truth)[cells] ** 2)), np.sqrt(np.mean((dsm - truth)[cells] ** 2)))
        rows.append(
            {
                "class": CLASSES[code],
                "cells": int(cells.sum()),
                "DTM - true DTM": rms[code][0],
                "DSM - true DTM": rms[code][1],
            }
        )
    figures.table("Bulldozer on the simulated true DSM (5 m), RMS by class (m)", rows)
    assert rms[BARE][0] < 1.0 and rms[CROPS][0] < 1.0
    # issue 40's aim, the DTM's error at most half of the DSM's departure from the DTM: the town's (0.77 against 5.81
    # m); the forest's is 0.67 of it (10.2 against 15.2 m): its ground is never seen (docs/validation.md#extract-dtm)
    assert rms[CITY][0] < 0.5 * rms[CITY][1] and rms[FOREST][0] < 0.75 * rms[FOREST][1]


def test_dhm_is_the_dsm_less_the_dtm_and_nodata_stays(scene, extracted):
    dsm, dtm, dhm = scene["dsm_values"], extracted["dtm"], extracted["dhm"]
    ok = np.isfinite(dsm)
    assert (~ok).any() and np.isnan(dtm[~ok]).all() and np.isnan(dhm[~ok]).all()
    np.testing.assert_allclose(dhm[ok], (dsm - dtm)[ok], atol=1e-3)
    assert set(np.unique(extracted["mask"][np.isfinite(extracted["mask"])])) <= {0, 1, 2}


def test_tiles_agree_with_one_run(scene, extracted, figures):
    folder = scene["folder"]
    out = DtmOutputs(str(folder / "dtm_tiled.tif"))
    extract_dtm(scene["dsm"], out, DtmParams(tile=256, execution=Execution("processes", 2)))  # windows of 256
    tiled, whole = read(out.dtm), extracted["dtm"]
    ok = np.isfinite(tiled) & np.isfinite(whole)
    d = np.abs(tiled - whole)[ok]
    figures.report(
        "windows of 256 against one run: RMS, 99th percentile, largest",
        [np.sqrt(np.mean(d**2)), np.percentile(d, 99), d.max()],
        "m",
    )
    figures.report("cells beyond 0.5 m", 100 * np.mean(d > 0.5), "%")
    assert np.sqrt(np.mean(d**2)) < 0.05 and np.percentile(d, 99) < 0.01


def test_a_hole_filled_and_flagged_and_a_void_dsm_refused(scene, tmp_path):
    """A hole of 20 x 20 cells punched inside the DSM: Bulldozer fills it, the mask says so (1), the DHM has no value
    there. A DSM of nodata only: refused, nothing written."""
    ds = gdal.Open(scene["dsm"])
    values, nodata = ds.GetRasterBand(1).ReadAsArray(), ds.GetRasterBand(1).GetNoDataValue()
    values[400:420, 400:420] = nodata
    holed = str(tmp_path / "holed.tif")
    out = gdal.GetDriverByName("GTiff").CreateCopy(holed, ds)
    out.GetRasterBand(1).WriteArray(values)
    out = None
    outputs = DtmOutputs(str(tmp_path / "dtm.tif"), str(tmp_path / "dhm.tif"), str(tmp_path / "mask.tif"))
    extract_dtm(holed, outputs, DtmParams(execution=Execution("processes", 1)))
    dtm, dhm, mask = (read(p) for p in (outputs.dtm, outputs.dhm, outputs.mask))
    hole = (slice(400, 420), slice(400, 420))
    assert (mask[hole] == 1).all() and np.isfinite(dtm[hole]).all() and np.isnan(dhm[hole]).all()
    void = str(tmp_path / "void.tif")
    out = gdal.GetDriverByName("GTiff").CreateCopy(void, ds)
    out.GetRasterBand(1).Fill(nodata)
    out = None
    with pytest.raises(InputError, match="holds no valid height"):
        extract_dtm(void, DtmOutputs(str(tmp_path / "void_dtm.tif")), DtmParams(tile=256))
    assert not (tmp_path / "void_dtm.tif").exists()


def test_a_dsm_in_degrees_is_refused(small_scene, tmp_path):
    with pytest.raises(InputError, match="longitude/latitude: Bulldozer works in metres"):
        extract_dtm(small_scene["dsm"], DtmOutputs(str(tmp_path / "x.tif")), DtmParams())
    assert not (tmp_path / "x.tif").exists()


@pytest.mark.parametrize("size", [100, 256, 257, 384, 385, 448, 449, 1000, 4097])
def test_every_window_has_the_tiles_size_and_holds_its_margin(size):
    """Windows of 256 cells, margins of 64: each window is 256 cells (the axis where it is shorter), inside the
    axis, and holds its inner tile with a margin on each side wherever the axis goes on; the inner tiles cover the
    axis once, and no more of them than windows of 256 need."""
    window, margin = 256, 64
    covered = np.zeros(size, int)
    tiles = axis_tiles(size, window, margin)
    for c0, c1 in tiles:
        w0, w1 = window_of(c0, c1, margin, window, size)
        assert w1 - w0 == min(window, size) and 0 <= w0 and w1 <= size
        assert w0 <= max(c0 - margin, 0) and w1 >= min(c1 + margin, size)
        covered[c0:c1] += 1
    assert np.all(covered == 1)
    fewest = 1 if size <= window else 2 + max(0, -(-(size - 2 * (window - margin)) // (window - 2 * margin)))
    assert len(tiles) == fewest


def test_the_tile_a_refusal_asks_for_is_the_least_that_does():
    """For every margin, the tile the message names is accepted and one cell less is refused; a DSM that fits in one
    window needs no margin."""
    large = (100_000, 100_000)
    for margin in range(64, 400):
        with pytest.raises(InputError) as refused:
            DtmParams(tile=3 * margin - 1).check_margin(margin, large)
        need = int(str(refused.value).rsplit("at least ", 1)[1].split()[0])
        DtmParams(tile=need).check_margin(margin, large)
        with pytest.raises(InputError):
            DtmParams(tile=need - 1).check_margin(margin, large)
        refused = None
    DtmParams(tile=200).check_margin(300, (192, 200))  # windows of 192 x 200


def test_a_tile_too_small_for_the_objects_is_refused(scene, tmp_path):
    with pytest.raises(InputError, match="give a tile of at least 960 cells"):  # 2 x 800 m / 5 m = 320 cells a margin
        extract_dtm(scene["dsm"], DtmOutputs(str(tmp_path / "dtm.tif")), DtmParams(max_object_size=800, tile=512))
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("tile", [192, 256, 1000, 2048, 2100, 4096])
def test_the_windows_columns_are_a_multiple_of_16_not_of_128(tile):
    """Bulldozer runs 2.5 times slower on rows of 2048 cells than of 2032 (bench_bulldozer_widths)."""
    columns, rows = DtmParams(tile=tile).window()
    assert rows == tile and tile - 32 < columns <= tile and columns % 16 == 0 and columns % 128 != 0
