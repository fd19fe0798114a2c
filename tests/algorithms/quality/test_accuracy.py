"""Accuracy assessment (algorithms/quality): statistics against plain numpy, the reference resampled
at points (numpy bilinear) and onto a DEM grid (numpy block means, an exact plane), EGM96 handling,
references in another CRS, no overlap, nodata, classes of the simulator's classes.tif and of
polygons (OGR point-in-polygon), the dh raster and the self-contained HTML report."""

import base64
import csv
import os
import re

import numpy as np
import pytest
from osgeo import gdal, ogr, osr

from pushbroom.algorithms.crs import egm96_undulation
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.quality import assessment, report
from pushbroom.algorithms.quality.assess_accuracy import AssessParams, assess_accuracy
from pushbroom.algorithms.quality.assessment import Labelling, assess, summarized
from pushbroom.algorithms.quality.classes import FLAT, MOUNTAINOUS, NO_CLASS, ClassRaster, PolygonClasses
from pushbroom.algorithms.quality.height_differences import (
    Reference,
    dem_differences,
    point_differences,
    reference_at_points,
)
from pushbroom.algorithms.quality.statistics import STEP, cumulative, labelled, summarize
from pushbroom.algorithms.simulation.terrain import BARE, CLASSES, CROPS, FOREST
from pushbroom.algorithms.surface.geotiff import NODATA
from pushbroom.algorithms.surface.point_input import read_points
from pushbroom.algorithms.surface.pointcloud import write_point_cloud
from tests.helpers.feedback import Feedback
from tests.helpers.osr_oracle import utm

UTM16 = 32616


def srs_of(epsg):
    s = osr.SpatialReference()
    s.ImportFromEPSG(epsg)
    s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return s


def write_raster(path, values, gt, epsg, nodata=None):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), values.shape[1], values.shape[0], 1, gdal.GDT_Float64)
    ds.SetGeoTransform(gt)
    ds.SetProjection(srs_of(epsg).ExportToWkt())
    if nodata is not None:
        ds.GetRasterBand(1).SetNoDataValue(nodata)
    ds.GetRasterBand(1).WriteArray(values)
    ds = None
    return str(path)


def read(path):
    ds = gdal.Open(str(path))
    return ds.ReadAsArray().astype(float), ds.GetGeoTransform()


def numpy_bilinear(values, gt, x, y):
    """Plain bilinear interpolation between cell centres (NaN outside the centres' hull)."""
    c, r = (x - gt[0]) / gt[1] - 0.5, (y - gt[3]) / gt[5] - 0.5
    out = np.full(len(x), np.nan)
    ok = (c >= 0) & (r >= 0) & (c <= values.shape[1] - 1) & (r <= values.shape[0] - 1)
    i, j = np.minimum(r[ok].astype(int), values.shape[0] - 2), np.minimum(c[ok].astype(int), values.shape[1] - 2)
    fr, fc = r[ok] - i, c[ok] - j
    out[ok] = (values[i, j] * (1 - fc) + values[i, j + 1] * fc) * (1 - fr) + (
        values[i + 1, j] * (1 - fc) + values[i + 1, j + 1] * fc
    ) * fr
    return out


def random_lonlat(path, n, seed=0, margin=10):
    values, gt = read(path)
    rng = np.random.default_rng(seed)
    rows, cols = values.shape
    return (
        gt[0] + rng.uniform(margin, cols - margin, n) * gt[1],
        gt[3] + rng.uniform(margin, rows - margin, n) * gt[5],
    )


@pytest.fixture(scope="module")
def utm_dem(small_scene, tmp_path_factory):
    """The simulator's DTM warped to a 10 m UTM 16N grid (the DEM under test)."""
    path = tmp_path_factory.mktemp("accuracy") / "dem_utm.tif"
    gdal.Warp(
        str(path),
        small_scene["dtm"],
        dstSRS=f"EPSG:{UTM16}",
        xRes=10,
        yRes=10,
        resampleAlg="bilinear",
        outputType=gdal.GDT_Float64,
        dstNodata=-9999,
    )
    return str(path)


# --- statistics -------------------------------------------------------------------------------------


def test_statistics_against_numpy():
    rng = np.random.default_rng(3)
    dh = np.concatenate([rng.normal(0.4, 1.5, 5000), rng.normal(12, 4, 300), [np.nan, np.inf]])
    s = summarize(dh)
    v = dh[np.isfinite(dh)]
    a = np.abs(v)
    assert s.n == v.size
    np.testing.assert_allclose(
        [s.min, s.mean, s.max, s.rms, s.sigma],
        [v.min(), v.mean(), v.max(), np.sqrt(np.mean(v**2)), np.std(v, ddof=1)],
        rtol=1e-9,
    )
    # the robust statistics are those of dh counted in 1 mm bins (mergeable over the parts of a run)
    assert abs(s.median - np.median(v)) <= STEP / 2
    assert abs(s.nmad - 1.4826 * np.median(np.abs(v - np.median(v)))) <= 1.4826 * STEP
    assert abs(s.q95 - np.percentile(a, 95)) <= STEP / 2
    np.testing.assert_allclose(
        s.shares, [100 * np.mean(a < 2), 100 * np.mean((a >= 2) & (a <= 5)), 100 * np.mean(a > 5)], rtol=1e-12
    )
    assert s.nmad < s.sigma  # the outliers inflate sigma, not NMAD


def test_shares_and_nmad_on_a_known_array():
    s = summarize([-6.0, -3.0, -1.0, 0.0, 1.0, 2.0, 5.0, 5.5])
    assert s.shares == (37.5, 37.5, 25.0)  # |dh| < 2: 3 of 8; 2..5: 3; > 5: 2
    assert s.median == 0.5
    assert s.nmad == pytest.approx(1.4826 * np.median(np.abs(np.array([-6, -3, -1, 0, 1, 2, 5, 5.5]) - 0.5)))
    assert summarize([]).n == 0


def test_nested_classes_drop_the_worst_class_first():
    rng = np.random.default_rng(4)
    labels = np.repeat([1, 2, 3], 1000)
    dh = rng.normal(0, 1, 3000) * np.repeat([1.0, 5.0, 2.0], 1000)
    rows = cumulative(labelled(dh, labels), {1: "open", 2: "trees", 3: "city"})
    assert [name for name, _ in rows] == ["open+city+trees", "open+city", "open"]
    assert [s.n for _, s in rows] == [3000, 2000, 1000]
    np.testing.assert_allclose(rows[1][1].rms, np.sqrt(np.mean(dh[labels != 2] ** 2)))


# --- the reference at points ------------------------------------------------------------------------


def test_reference_at_points_is_bilinear_on_the_simulated_dsm(small_scene, figures):
    lon, lat = random_lonlat(small_scene["dsm"], 2000)
    href, slope = reference_at_points(Reference(small_scene["dsm"]), lon, lat, srs_of(4326))
    values, gt = read(small_scene["dsm"])
    expected = numpy_bilinear(values, gt, lon, lat)
    assert np.isfinite(href).all()
    figures.report("reference at 2000 points vs numpy bilinear, max |diff|", np.max(np.abs(href - expected)), "m")
    np.testing.assert_allclose(href, expected, atol=1e-9)
    assert np.all((slope >= 0) & (slope < 90))


def test_reference_in_another_crs_is_reprojected_not_refused(tmp_path, figures):
    """A UTM plane h = 100 + 0.02 dE - 0.01 dN (bilinear reproduces it exactly) against points in
    WGS 84 lon/lat whose heights lie on the plane (their UTM coordinates from an OSR oracle)."""
    lon = np.random.default_rng(5).uniform(-84.2, -84.17, 500)
    lat = np.random.default_rng(6).uniform(36.6, 36.63, 500)
    x, y = utm(lon, lat, UTM16)
    e0, n1 = np.floor(x.min()) - 100, np.floor(y.max()) + 100
    cols, rows = int(x.max() - e0) // 10 + 10, int(n1 - y.min()) // 10 + 10
    e, n = np.meshgrid(e0 + 10 * (np.arange(cols) + 0.5), n1 - 10 * (np.arange(rows) + 0.5))
    plane = lambda e, n: 100 + 0.02 * (e - e0) - 0.01 * (n - n1)
    reference = write_raster(tmp_path / "plane.tif", plane(e, n), (e0, 10, 0, n1, 0, -10), UTM16)
    cloud = tmp_path / "points.gpkg"
    write_point_cloud(cloud, lon, lat, plane(x, y), {"group": np.full(500, 3, np.uint8)}, crs=4326)
    d = point_differences(cloud, Reference(reference))
    assert d.dh.size == 500
    figures.report("points in EPSG:4326 vs a UTM plane, max |dh|", np.max(np.abs(d.dh)), "m")
    assert np.max(np.abs(d.dh)) < 1e-6
    np.testing.assert_allclose(d.slope, np.degrees(np.arctan(np.hypot(0.02, 0.01))), atol=1e-9)


def test_point_clouds_read_back(tmp_path):
    rng = np.random.default_rng(7)
    lon, lat, h = rng.uniform(-84.2, -84.19, 50), rng.uniform(36.6, 36.61, 50), rng.uniform(250, 400, 50)
    group = rng.integers(1, 4, 50).astype(np.uint8)
    for name in ("p.las", "p.gpkg"):
        write_point_cloud(tmp_path / name, lon, lat, h, {"group": group}, crs=UTM16)
        cloud = read_points(tmp_path / name)
        ex, ey = utm(lon, lat, UTM16)
        np.testing.assert_allclose(
            np.column_stack([cloud.x, cloud.y, cloud.z]), np.column_stack([ex, ey, h]), atol=1e-3
        )
        assert cloud.srs.GetAuthorityCode(None) == str(UTM16)
        np.testing.assert_array_equal(cloud.fields["group"], group)


# --- the reference on a DEM grid ----------------------------------------------------------------------


def test_finer_reference_is_averaged_onto_the_dem_grid(small_scene, tmp_path, figures):
    """A DEM of 2 x 2 block means of the simulated DTM (numpy) against the DTM itself: the reference
    averaged onto the DEM's cells is the same block mean, dh = 0."""
    values, gt = read(small_scene["dtm"])
    rows, cols = (s // 2 * 2 for s in values.shape)
    means = values[:rows, :cols].reshape(rows // 2, 2, cols // 2, 2).mean(axis=(1, 3))
    dem = write_raster(tmp_path / "mean.tif", means, (gt[0], 2 * gt[1], 0, gt[3], 0, 2 * gt[5]), 4326)
    d = dem_differences(dem, Reference(small_scene["dtm"]))
    assert d.dh.size == means.size
    figures.report("2x2 block means vs the averaged reference, max |dh|", np.max(np.abs(d.dh)), "m")
    assert np.max(np.abs(d.dh)) < 1e-6


def test_coarser_reference_is_bilinear_on_the_dem_grid(tmp_path):
    e0, n0 = 749000.0, 4053000.0
    plane = lambda e, n: 300 + 0.05 * (e - e0) + 0.03 * (n - n0)
    e, n = np.meshgrid(e0 + 40 * (np.arange(50) + 0.5), n0 + 2000 - 40 * (np.arange(50) + 0.5))
    reference = write_raster(tmp_path / "coarse.tif", plane(e, n), (e0, 40, 0, n0 + 2000, 0, -40), UTM16)
    e, n = np.meshgrid(e0 + 10 * (np.arange(200) + 0.5), n0 + 2000 - 10 * (np.arange(200) + 0.5))
    dem = write_raster(tmp_path / "dem.tif", plane(e, n) + 1.5, (e0, 10, 0, n0 + 2000, 0, -10), UTM16)
    d = dem_differences(dem, Reference(reference))
    inner = d.grid.values[4:-4, 4:-4]  # GDAL extrapolates within half a reference cell of the edge
    assert np.isfinite(inner).all()
    np.testing.assert_allclose(inner, 1.5, atol=1e-6)


def test_dem_in_utm_against_the_geographic_dsm(small_scene, utm_dem, figures):
    """The UTM DEM made from the DTM against the DTM: only resampling differences; against the DSM:
    the canopy and buildings, positive, in forest and city."""
    same = dem_differences(utm_dem, Reference(small_scene["dtm"]))
    s = summarize(same.dh)
    figures.table(
        "UTM 10 m DEM (bilinear from the DTM) vs the DTM averaged onto it (m)", [{"mean": s.mean, "RMS": s.rms}]
    )
    assert abs(s.mean) < 0.1 and s.rms < 1.0
    dsm = dem_differences(utm_dem, Reference(small_scene["dsm"]))
    assert summarize(dsm.dh).mean < -1.0  # DEM = DTM lies below the DSM's canopy


# --- datum, overlap, nodata ---------------------------------------------------------------------------


def test_egm96_reference(small_scene, tmp_path, figures):
    values, gt = read(small_scene["dsm"])
    lon, lat = (gt[0] + (np.arange(values.shape[1]) + 0.5) * gt[1], gt[3] + (np.arange(values.shape[0]) + 0.5) * gt[5])
    lon, lat = np.meshgrid(lon, lat)
    undulation = egm96_undulation(lon, lat)
    geoid = write_raster(tmp_path / "dsm_egm96.tif", values - undulation, gt, 4326)
    plon, plat = random_lonlat(small_scene["dsm"], 500, seed=8)
    h = numpy_bilinear(values, gt, plon, plat)
    cloud = tmp_path / "on_dsm.gpkg"
    write_point_cloud(cloud, plon, plat, h, crs=4326)
    right = point_differences(cloud, Reference(geoid, "orthometric"))
    wrong = point_differences(cloud, Reference(geoid, "ellipsoidal"))
    n = egm96_undulation(plon, plat)
    figures.report("EGM96 N, mean", n.mean(), "m")
    figures.report("dh with the geoid handled, max |dh|", np.max(np.abs(right.dh)), "m")
    assert np.max(np.abs(right.dh)) < 1e-3
    np.testing.assert_allclose(wrong.dh, n, atol=1e-3)
    dem = write_raster(tmp_path / "dem_egm96.tif", values - undulation, gt, 4326)
    d = dem_differences(dem, Reference(small_scene["dsm"]), dem_datum="orthometric")
    assert np.max(np.abs(d.dh)) < 1e-3


def test_no_overlap_is_a_clear_error(small_scene, utm_dem, tmp_path):
    values, gt = read(small_scene["dsm"])
    far = write_raster(tmp_path / "far.tif", values, (gt[0] + 2.0, gt[1], 0, gt[3], 0, gt[5]), 4326)
    lon, lat = random_lonlat(small_scene["dsm"], 100)
    cloud = tmp_path / "p.gpkg"
    write_point_cloud(cloud, lon, lat, np.full(100, 300.0))
    with pytest.raises(InputError, match="does not overlap"):
        point_differences(cloud, Reference(far))
    with pytest.raises(InputError, match="does not overlap"):
        dem_differences(utm_dem, Reference(far))


def test_nodata_is_left_out(small_scene, utm_dem, tmp_path):
    values, gt = read(small_scene["dsm"])
    holed = values.copy()
    holed[:, : values.shape[1] // 2] = -32768.0
    reference = write_raster(tmp_path / "holed.tif", holed, gt, 4326, nodata=-32768.0)
    lon, lat = random_lonlat(small_scene["dsm"], 1000, seed=9)
    cloud = tmp_path / "p.gpkg"
    write_point_cloud(cloud, lon, lat, numpy_bilinear(values, gt, lon, lat))
    d = point_differences(cloud, Reference(reference))
    west = (lon - gt[0]) / gt[1] < values.shape[1] // 2 + 0.5
    assert d.dh.size == int((~west).sum())
    assert d.excluded["outside the reference or next to its nodata"] == int(west.sum())
    assert np.max(np.abs(d.dh)) < 1e-6  # no nodata value leaks into a difference
    on_dem = dem_differences(utm_dem, Reference(reference))
    assert on_dem.dh.size and np.all(np.abs(on_dem.dh) < 100)
    empty = write_raster(tmp_path / "empty.tif", np.full_like(values, -32768.0), gt, 4326, nodata=-32768.0)
    with pytest.raises(InputError, match="nodata"):
        dem_differences(empty, Reference(small_scene["dsm"]))
    with pytest.raises(InputError, match="nodata"):
        point_differences(cloud, Reference(empty))


# --- classes ------------------------------------------------------------------------------------------


def test_per_class_tables_on_the_simulated_classes(small_scene, tmp_path, figures):
    """Points on the true DSM against the true DTM: dh = 0 on fields, the canopy height in forest."""
    values, gt = read(small_scene["dsm"])
    classes, cgt = read(small_scene["classes"])
    lon, lat = random_lonlat(small_scene["dsm"], 5000, seed=10)
    cloud = tmp_path / "on_dsm.las"
    write_point_cloud(cloud, lon, lat, numpy_bilinear(values, gt, lon, lat), {"group": np.full(5000, 3, np.uint8)})
    source = ClassRaster(small_scene["classes"])
    assert source.names == {k: v for k, v in CLASSES.items() if k and np.any(classes == k)}
    [a] = assess(Reference(small_scene["dtm"]), points=cloud, labelling=Labelling(classes=source))
    d = a.differences
    assert d.dh.size == 5000
    expected = classes[((lat - cgt[3]) / cgt[5]).astype(int), ((lon - cgt[0]) / cgt[1]).astype(int)]
    np.testing.assert_array_equal(a.classes, expected)
    rows = dict(next(r for name, r, _ in report.tables(summarized(a)) if name == "per class"))
    for value, name in source.names.items():
        if np.any(expected == value):
            assert rows[name].n == int(np.sum(expected == value))
            np.testing.assert_allclose(rows[name].rms, np.sqrt(np.mean(d.dh[expected == value] ** 2)))
    figures.report("points on the DSM vs the DTM, median per class", {n: s.median for n, s in rows.items()}, "m")
    assert abs(rows[CLASSES[BARE]].median) < 1e-3 and abs(rows[CLASSES[CROPS]].median) < 1e-3  # LAS: 1 mm z
    assert rows[CLASSES[FOREST]].median > 5.0
    assert set(np.unique(a.terrain)) <= {FLAT, MOUNTAINOUS}


def test_a_raster_of_heights_is_no_class_raster(small_scene, tmp_path):
    """Issue 36: the float DSM given as the class raster made hundreds of 'classes'. A class raster holds whole
    numbers, few of them, in any data type: a float copy of classes.tif is one, the DSM is not, nor the DSM
    rounded to whole metres in Int16 (an SRTM tile)."""

    def copy(source, name, kind):
        ds = gdal.Translate(str(tmp_path / name), source, outputType=kind)
        ds.FlushCache()
        return str(tmp_path / name)

    classes = ClassRaster(copy(small_scene["classes"], "classes_float.tif", gdal.GDT_Float32))
    assert classes.names == ClassRaster(small_scene["classes"]).names
    with pytest.raises(
        InputError,
        match=rf"the class raster {small_scene['dsm']} holds \d+ distinct values "
        r"\(Float32, such as [-0-9.]+\), not class codes: .*Is it a height raster\?",
    ):
        ClassRaster(small_scene["dsm"])
    whole = copy(small_scene["dsm"], "dsm_int16.tif", gdal.GDT_Int16)
    with pytest.raises(
        InputError,
        match=r"holds \d{3,} distinct values \(Int16, \d+ \.\. \d+\), not class codes: a "
        r"class raster holds whole numbers, at most 100 classes",
    ):
        ClassRaster(whole)


def test_classes_on_a_dem_grid(small_scene, utm_dem):
    [a] = assess(
        Reference(small_scene["dsm"]), dem=utm_dem, labelling=Labelling(classes=ClassRaster(small_scene["classes"]))
    )
    rows = dict(next(r for name, r, _ in report.tables(summarized(a)) if name == "per class"))
    assert rows[CLASSES[FOREST]].mean < -5.0 < rows[CLASSES[BARE]].mean  # DTM below the canopy
    assert sum(s.n for s in rows.values()) + int(np.sum(a.classes == NO_CLASS)) == a.differences.dh.size


def test_polygon_classes_against_ogr(tmp_path):
    square = ogr.CreateGeometryFromWkt(
        "POLYGON ((0 0, 100 0, 100 100, 0 100, 0 0), (40 40, 60 40, 60 60, 40 60, 40 40))"
    )
    triangle = ogr.CreateGeometryFromWkt("MULTIPOLYGON (((150 0, 250 0, 200 90, 150 0)))")
    source = PolygonClasses([square.ExportToWkb(), triangle], ["open", "city"], UTM16)
    assert source.names == {1: "city", 2: "open"}
    rng = np.random.default_rng(11)
    x, y = rng.uniform(-10, 260, 3000), rng.uniform(-10, 110, 3000)
    got = source.at_points(x, y, srs_of(UTM16))
    expected = np.zeros(3000, int)
    for k in range(3000):
        p = ogr.CreateGeometryFromWkt(f"POINT ({x[k]} {y[k]})")
        expected[k] = 2 if square.Contains(p) else 1 if triangle.Contains(p) else 0
    np.testing.assert_array_equal(got, expected)


# --- outputs ------------------------------------------------------------------------------------------

CSV_STATS = (
    "min",
    "mean",
    "max",
    "rms",
    "sigma",
    "median",
    "nmad",
    "q95_abs",
    "pct_below_2m",
    "pct_2_to_5m",
    "pct_above_5m",
)


def test_parts_give_the_wholes_statistics_and_dh_raster(small_scene, utm_dem, tmp_path, monkeypatch):
    """The step reads the cloud in chunks and the DEM in windows: the same tables as every difference held at
    once (assess), and a dh raster equal to the whole DEM's dh grid."""
    lon, lat = random_lonlat(small_scene["dsm"], 3000, seed=13)
    values, gt = read(small_scene["dsm"])
    cloud = tmp_path / "p.las"
    write_point_cloud(
        cloud,
        lon,
        lat,
        numpy_bilinear(values, gt, lon, lat) + np.linspace(-3, 3, 3000),
        {"group": np.random.default_rng(2).integers(1, 4, 3000).astype(np.uint8)},
    )
    monkeypatch.setattr(assessment, "CHUNK", 700)  # 5 chunks
    monkeypatch.setattr(assessment, "TILE", 64)  # 3 x 3 windows of the 10 m UTM DEM
    monkeypatch.setattr(assessment, "MAP_CELLS", 50)  # a map of every 4th cell
    params = AssessParams(
        small_scene["dtm"],
        str(tmp_path / "report.html"),
        points=str(cloud),
        dem=utm_dem,
        class_raster=small_scene["classes"],
        table=str(tmp_path / "parts.csv"),
        dh=str(tmp_path / "dh.tif"),
        coregister=False,  # the parts against the whole: the DEM as it lies
    )
    assess_accuracy(params)
    whole = [
        summarized(a)
        for a in assess(
            Reference(small_scene["dtm"]),
            points=cloud,
            dem=utm_dem,
            labelling=Labelling(classes=ClassRaster(small_scene["classes"])),
        )
    ]
    report.write_csv(tmp_path / "whole.csv", whole)
    parts, once = (list(csv.DictReader(open(tmp_path / name))) for name in ("parts.csv", "whole.csv"))
    assert len(parts) == len(once) > 20
    for a, b in zip(parts, once):
        assert (a["data"], a["table"], a["label"]) == (b["data"], b["table"], b["label"])
        if a["data"] == "DEM cells" and a["label"] != "dh":
            # along the reference's (and the class raster's) last row, gdalwarp of a window leaves a few cells
            # without a value that the whole grid's warp gives one: their slope or class (5 of 174 749 here)
            assert abs(int(a["n"]) - int(b["n"])) <= 1e-4 * int(b["n"])
            np.testing.assert_allclose([float(a[k]) for k in CSV_STATS], [float(b[k]) for k in CSV_STATS], atol=0.02)
            continue
        assert a["n"] == b["n"], (a["table"], a["label"])
        np.testing.assert_allclose([float(a[k]) for k in CSV_STATS], [float(b[k]) for k in CSV_STATS], atol=1e-3)
    assert sorted(os.listdir(tmp_path)) == ["dh.tif", "p.las", "parts.csv", "report.html", "whole.csv"]
    d = dem_differences(utm_dem, Reference(small_scene["dtm"]))
    ds = gdal.Open(str(tmp_path / "dh.tif"))
    band = ds.GetRasterBand(1)
    assert band.GetNoDataValue() == NODATA and band.GetOverviewCount() > 0
    assert ds.GetMetadata("IMAGE_STRUCTURE").get("COMPRESSION") == "DEFLATE" and band.GetBlockSize()[1] > 1
    assert ds.GetSpatialRef().GetAuthorityCode(None) == str(UTM16)
    out = band.ReadAsArray().astype(float)
    np.testing.assert_array_equal(out == NODATA, ~d.valid)
    np.testing.assert_allclose(out[d.valid], d.grid.values[d.valid], atol=1e-4)


def test_html_report_is_self_contained(small_scene, utm_dem, tmp_path):
    lon, lat = random_lonlat(small_scene["dsm"], 3000, seed=12)
    values, gt = read(small_scene["dsm"])
    cloud = tmp_path / "p.las"
    write_point_cloud(
        cloud,
        lon,
        lat,
        numpy_bilinear(values, gt, lon, lat),
        {"group": np.random.default_rng(1).integers(1, 4, 3000).astype(np.uint8)},
    )
    assessed = assess(
        Reference(small_scene["dtm"]),
        points=cloud,
        dem=utm_dem,
        labelling=Labelling(classes=ClassRaster(small_scene["classes"])),
    )
    summaries = [summarized(a) for a in assessed]
    page = report.write_report(tmp_path / "report.html", "Accuracy", summaries, [("reference", small_scene["dtm"])])
    text = open(page, encoding="utf-8").read()
    assert not re.search(r"(src|href)\s*=\s*['\"](?!data:)", text) and "<link" not in text and "<script" not in text
    images = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", text)
    assert len(images) == 2 + 3 + 2  # per input a map; histograms per group, class, terrain (no groups for the DEM)
    assert all(base64.b64decode(i).startswith(b"\x89PNG") for i in images)
    for needle in (
        "Kornus et al. 2006, Tables 6, 7",
        "Zhang and Gruen 2004, Tables 2-3",
        "Point group 3",
        "RMSE (m)",
        "NMAD",
        CLASSES[FOREST],
        small_scene["dtm"],
        "mountainous",
    ):
        assert needle in text
    table = report.write_csv(tmp_path / "stats.csv", summaries)
    rows = list(csv.DictReader(open(table)))
    first = next(r for r in rows if r["data"] == "object points" and r["label"] == "dh")
    assert int(first["n"]) == assessed[0].differences.dh.size
    np.testing.assert_allclose(float(first["rms"]), summarize(assessed[0].differences.dh).rms, atol=1e-4)


def test_cancel_and_bad_input(small_scene, utm_dem, tmp_path):
    with pytest.raises(CancelledError):
        assess(Reference(small_scene["dtm"]), dem=utm_dem, feedback=Feedback(cancel_after=0))
    with pytest.raises(InputError, match="point cloud, a DEM or both"):
        assess(Reference(small_scene["dtm"]))
    with pytest.raises(InputError, match="orthometric"):
        dem_differences(utm_dem, Reference(small_scene["dtm"]), dem_datum="egm2008")
    empty = tmp_path / "empty.gpkg"
    write_point_cloud(empty, [], [], [], crs=4326)
    with pytest.raises(InputError, match="no point"):
        point_differences(empty, Reference(small_scene["dtm"]))
    two = tmp_path / "two.gpkg"
    lon, lat = random_lonlat(small_scene["dsm"], 2)
    write_point_cloud(two, lon, lat, [300.0, 310.0], crs=4326)
    assert point_differences(two, Reference(small_scene["dtm"])).dh.size == 2
