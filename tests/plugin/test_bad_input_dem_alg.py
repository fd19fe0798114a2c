"""Bad DEMs through Processing (issue 19): a DEM without a CRS in createblock and orthorectify is refused
with how to assign one (before: 'does not overlap'), also through qgis_process; SRTM-like voids (-32767, not
flagged as nodata) give a warning in createblock, orthorectify and assessaccuracy, and the DEM_NODATA /
REFERENCE_NODATA parameters make them nodata (before: a wrong orthoimage over the voids, silently)."""

import csv

import numpy as np
import pytest
from osgeo import gdal, osr
from qgis import processing

from pushbroom.algorithms.crs import reproject, srs
from tests.helpers.bad_inputs import VOID, copy_dem, processing_error


@pytest.fixture(scope="module")
def dems(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad_dems_alg")
    return {
        "nocrs": copy_dem(small_scene["dsm"], folder / "nocrs.tif", crs=False),
        "voids": copy_dem(small_scene["dsm"], folder / "voids.tif", voids=True),
        "image": small_scene["images"]["HRG"]["imagery"],
        "dsm": small_scene["dsm"],
    }


def test_a_dem_without_crs_is_refused_by_createblock_and_orthorectify(pushbroom_provider, dems, tmp_path):
    hint = (
        f"has no coordinate reference system, so where its cells lie is unknown: assign the CRS of its "
        f"coordinates, e.g. 'gdal_edit.py -a_srs EPSG:4326 {dems['nocrs']}'"
    )
    for algorithm, parameters in (
        (
            "pushbroom:createblock",
            {"IMAGES": [dems["image"]], "DEM": dems["nocrs"], "OUTPUT": str(tmp_path / "b.gpkg")},
        ),
        ("pushbroom:orthorectify", {"IMAGE": dems["image"], "DEM": dems["nocrs"], "OUTPUT": str(tmp_path / "o.tif")}),
    ):
        message = processing_error(algorithm, parameters)
        # the engine's reason and remedy, not the symptom it used to give
        assert f"the DEM {dems['nocrs']} {hint}" in message and "overlap" not in message
    assert not list(tmp_path.iterdir())  # nothing written


@pytest.mark.slow
def test_qgis_process_orthorectify_with_a_dem_without_crs(qgis_process, dems, tmp_path):
    with pytest.raises(RuntimeError) as err:
        qgis_process(
            "run",
            "pushbroom:orthorectify",
            "--",
            f"IMAGE={dems['image']}",
            f"DEM={dems['nocrs']}",
            f"OUTPUT={tmp_path / 'o.tif'}",
        )
    # what the user reads on the terminal: the DEM, what it lacks and the command that fixes it
    assert f"the DEM {dems['nocrs']} has no coordinate reference system" in str(err.value)
    assert f"gdal_edit.py -a_srs EPSG:4326 {dems['nocrs']}" in str(err.value)  # the fix, ready to paste
    assert "Traceback" not in str(err.value)  # the engine's message, not a crash


def void_warnings(log):
    return [w for w in log.warnings if "cells at -32767 m, outside the heights of terrain on Earth" in w]


def test_createblock_warns_of_voids_and_takes_their_nodata_value(pushbroom_provider, dems, tmp_path, log):
    processing.run(
        "pushbroom:createblock",
        {"IMAGES": [dems["image"]], "DEM": dems["voids"], "OUTPUT": str(tmp_path / "a.gpkg")},
        feedback=log,
    )
    # one warning: the file, the 100 x 100 void cells, their value and how to declare it
    assert void_warnings(log) == [
        f"the DEM {dems['voids']} has 10000 cells at -32767 m, outside the heights of "
        "terrain on Earth (-500 .. 9000 m): voids that are not flagged as nodata, or "
        "heights in another unit. They are used as heights as they are; if they are voids, "
        "declare -32767 as the DEM's nodata value (the DEM nodata parameter, or "
        "gdal_edit.py -a_nodata -32767 on the file) and run again"
    ]
    log.warnings.clear()
    processing.run(
        "pushbroom:createblock",
        {"IMAGES": [dems["image"]], "DEM": dems["voids"], "DEM_NODATA": -32767, "OUTPUT": str(tmp_path / "b.gpkg")},
        feedback=log,
    )
    assert not void_warnings(log) and (tmp_path / "b.gpkg").exists()  # declared: no warning, block written


def cells_over_the_void(ortho, dsm):
    """The orthoimage's values at the cells whose centres lie over the void, 3 DSM cells inside its edge."""
    ds, ref = gdal.Open(ortho), gdal.Open(dsm)
    x0, dx, _, y0, _, dy = ds.GetGeoTransform()
    cols, rows = np.meshgrid(np.arange(ds.RasterXSize) + 0.5, np.arange(ds.RasterYSize) + 0.5)
    target = osr.SpatialReference(wkt=ds.GetProjection())
    lon, lat = reproject((x0 + cols * dx).ravel(), (y0 + rows * dy).ravel(), srs(target), srs(4326))
    lon0, dlon, _, lat0, _, dlat = ref.GetGeoTransform()
    c, r = (lon - lon0) / dlon, (lat - lat0) / dlat
    inside = (c > VOID[1].start + 3) & (c < VOID[1].stop - 3) & (r > VOID[0].start + 3) & (r < VOID[0].stop - 3)
    return ds.GetRasterBand(1).ReadAsArray().ravel()[inside]


def test_orthorectify_warns_of_voids_and_leaves_them_nodata_when_declared(pushbroom_provider, dems, tmp_path, log):
    run = {"IMAGE": dems["image"], "DEM": dems["voids"], "CELL_SIZE": 20.0}
    processing.run("pushbroom:orthorectify", dict(run, OUTPUT=str(tmp_path / "a.tif")), feedback=log)
    assert len(void_warnings(log)) == 1  # warned once, though the run goes on
    wrong = cells_over_the_void(str(tmp_path / "a.tif"), dems["dsm"])
    assert wrong.size > 100 and (wrong != 0).mean() > 0.5  # as given: image values over the void (warned)
    log.warnings.clear()
    processing.run("pushbroom:orthorectify", dict(run, DEM_NODATA=-32767, OUTPUT=str(tmp_path / "b.tif")), feedback=log)
    assert not void_warnings(log)  # declared: no warning
    assert np.all(cells_over_the_void(str(tmp_path / "b.tif"), dems["dsm"]) == 0)  # nodata (0) over the void


def test_assessaccuracy_warns_of_reference_voids_and_takes_their_nodata_value(pushbroom_provider, dems, tmp_path, log):
    run = {"REFERENCE": dems["voids"], "DEM": dems["dsm"], "REPORT": str(tmp_path / "r.html")}
    processing.run(
        "pushbroom:assessaccuracy", dict(run, DH=str(tmp_path / "a.tif"), TABLE=str(tmp_path / "a.csv")), feedback=log
    )
    warning = void_warnings(log)[0]
    assert warning.startswith(f"the reference DEM {dems['voids']} has ")  # names the reference
    assert "left out as voids; declare -32767 as its nodata value (the REFERENCE_NODATA parameter" in warning
    ds = gdal.Open(str(tmp_path / "a.tif"))
    dh = ds.ReadAsArray()
    valid = dh != ds.GetRasterBand(1).GetNoDataValue()
    # issue 36: the voids used as heights made 'mean dh 11072 m'; now left out, the DSM equals itself
    assert (~valid).sum() >= 10000 and np.abs(dh[valid]).max() < 1e-3
    table = list(csv.DictReader(open(tmp_path / "a.csv")))
    assert table and all(float(row["rms"]) < 1e-3 for row in table)  # every statistic of the DSM against itself
    log.warnings.clear()
    processing.run(
        "pushbroom:assessaccuracy", dict(run, REFERENCE_NODATA=-32767, DH=str(tmp_path / "b.tif")), feedback=log
    )
    ds = gdal.Open(str(tmp_path / "b.tif"))
    dh = ds.ReadAsArray()
    valid = dh != ds.GetRasterBand(1).GetNoDataValue()
    # declared: no warning, the void left out, the DSM equal to itself elsewhere
    assert not void_warnings(log) and (~valid).sum() >= 10000 and np.abs(dh[valid]).max() < 1e-3
