"""Bad DEMs (issue 19): a DEM without a CRS is refused with how to assign one (not 'does not overlap');
heights no terrain has (SRTM voids -32767 not flagged as nodata) give a warning naming the value and the
number of cells, and a declared nodata value makes them NaN, also through a warp; the accuracy assessment's
reference leaves them out as voids even undeclared (issue 36)."""

import re

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.dem import implausible_heights
from pushbroom.algorithms.dem_store import read_dem, store_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.quality.height_differences import Reference, dem_differences, reference_at_points
from tests.helpers.bad_inputs import VOID, VOID_CELLS, copy_dem
from tests.helpers.feedback import Feedback


@pytest.fixture(scope="module")
def dems(small_scene, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad_dems")
    voids = copy_dem(small_scene["dsm"], folder / "voids.tif", voids=True)
    utm = str(folder / "voids_utm.tif")
    gdal.Warp(utm, voids, dstSRS="EPSG:32616", xRes=10.0, yRes=10.0, resampleAlg="near", dstNodata=-9999)
    return {
        "nocrs": copy_dem(small_scene["dsm"], folder / "nocrs.tif", crs=False),
        "voids": voids,
        "utm": utm,
        "dsm": small_scene["dsm"],
    }


def test_a_dem_without_crs_is_refused_with_how_to_assign_one(dems, tmp_path):
    path = dems["nocrs"]
    expected = (
        f"the DEM {path} has no coordinate reference system, so where its cells lie is unknown: assign the "
        f"CRS of its coordinates, e.g. 'gdal_edit.py -a_srs EPSG:4326 {path}' for longitude/latitude in "
        "degrees (or the EPSG code of its map projection), and run again"
    )
    for read in (read_dem, lambda p: store_dem(p, tmp_path)):  # in memory, and the steps' way in
        with pytest.raises(InputError, match=f"^{re.escape(expected)}$"):
            read(path)


def test_implausible_heights_names_the_value_and_the_cells():
    assert implausible_heights(np.array([[-430.0, 8849.0], [np.nan, 0.0]])) is None  # Dead Sea, Everest, nodata
    heights = np.array([[-32768.0, -32767.0, 100.0], [-32768.0, 9500.0, np.nan]])
    message = implausible_heights(heights, "the DEM x.tif")
    # the count, the span and the most frequent value, and the remedy with that value
    assert message.startswith(
        "the DEM x.tif has 4 cells from -32768 to 9500 m (2 of them at -32768 m), outside "
        "the heights of terrain on Earth (-500 .. 9000 m)"
    )
    assert (
        "declare -32768 as the DEM's nodata value (the DEM nodata parameter, or gdal_edit.py -a_nodata -32768"
        in message
    )


def test_unflagged_voids_are_used_with_a_warning(dems):
    dem = read_dem(dems["voids"])
    # the file, the exact count of void cells and their value
    assert dem.implausible.startswith(f"the DEM {dems['voids']} has {VOID_CELLS} cells at -32767 m, outside")
    assert np.all(dem.heights[VOID] == -32767)  # used as given: the warning is the only safeguard
    assert read_dem(dems["dsm"]).implausible is None  # the simulated terrain is plausible


def test_declared_nodata_makes_the_voids_nan(dems):
    dem = read_dem(dems["voids"], nodata=-32767)
    clean = read_dem(dems["dsm"])
    outside = np.ones(dem.shape, bool)
    outside[VOID] = False
    assert dem.implausible is None and np.isnan(dem.heights[VOID]).all()  # declared: no warning, all NaN
    np.testing.assert_array_equal(dem.heights[outside], clean.heights[outside])  # the rest untouched


def test_declared_nodata_is_applied_before_a_warp(dems, tmp_path):
    warned = read_dem(dems["utm"])
    # undeclared, the voids are counted in the file's own (UTM) cells, before the warp
    assert f"the DEM {dems['utm']} has " in warned.implausible and "cells at -32767 m" in warned.implausible
    dem = store_dem(dems["utm"], tmp_path, nodata=-32767).whole()
    low, high = read_dem(dems["dsm"]).height_range
    # neither the file's nodata (-9999) nor the declared void value leaks into the bilinear warp to WGS 84:
    # every height within the terrain's range
    assert low - 1e-3 <= np.nanmin(dem.heights) and np.nanmax(dem.heights) <= high + 1e-3
    assert dem.implausible is None and np.isnan(dem.heights).sum() > VOID_CELLS / 2  # the hole is kept


def test_the_reference_of_the_assessment_warns_and_takes_a_nodata_value(dems):
    reference = read_dem(dems["dsm"])
    lon0, dlon, _, lat0, _, dlat = reference.geotransform
    rows, cols = np.mgrid[390:510, 290:410]  # the void's cells and a 10-cell ring around them
    lon, lat = lon0 + (cols.ravel() + 0.5) * dlon, lat0 + (rows.ravel() + 0.5) * dlat
    inside = ((rows >= 401) & (rows < 499) & (cols >= 301) & (cols < 399)).ravel()  # bilinear: void cells only
    ring = ((rows < 399) | (rows >= 501) | (cols < 299) | (cols >= 401)).ravel()
    log = Feedback()
    href, _ = reference_at_points(Reference(dems["voids"]), lon, lat, srs(4326), feedback=log)
    # issue 36: used as heights they made a 'mean dh' of 11 km; now voids, left out as declared ones would be ...
    assert np.isnan(href[inside]).all() and np.isfinite(href[ring]).all()
    # ... with the warning (pushInfo: this feedback has no pushWarning) naming the parameter that declares them
    assert [
        m
        for m in log.messages
        if m.startswith(f"the reference DEM {dems['voids']} has ")
        and "cells at -32767 m" in m
        and "They are left out as voids; declare -32767 as its nodata value (the REFERENCE_NODATA" in m
    ]
    log = Feedback()
    href, _ = reference_at_points(Reference(dems["voids"], nodata=-32767), lon, lat, srs(4326), feedback=log)
    assert np.isnan(href[inside]).all() and np.isfinite(href[ring]).all()  # the voids left out, the rest kept
    assert not any("-32767" in m for m in log.messages)  # declared: no warning


def test_a_dem_against_a_reference_with_declared_voids(dems):
    log = Feedback()
    d = dem_differences(dems["dsm"], Reference(dems["voids"], nodata=-32767), feedback=log)
    # the DSM against itself: dh = 0 wherever the reference has a height, the void cells left out
    assert d.excluded["outside the reference or on its nodata"] >= VOID_CELLS and np.abs(d.dh).max() < 1e-3
    assert not any("-32767" in m for m in log.messages)  # declared: no warning
    log = Feedback()
    undeclared = dem_differences(dems["dsm"], Reference(dems["voids"]), feedback=log)
    # undeclared: the same differences (the voids left out as implausible heights), and a warning
    assert np.array_equal(undeclared.dh, d.dh) and any("cells at -32767 m" in m for m in log.messages)
