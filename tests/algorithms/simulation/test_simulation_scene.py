"""Scene simulator end to end, on small (3 x 3 km) scenes: the simulated products are checked
against the truth model (SpotModel of truth/<image>/METADATA.DIM) that every later test relies on."""

import csv
import json
import os

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.geodesy import geodetic_to_ecef
from pushbroom.algorithms.sensors.spot_orientation import Corrections
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene, terrain
from tests.helpers.feedback import Feedback

gdal.UseExceptions()
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module", params=["spot5_triplet", "spot14_pair"])
def scene(request, simulated):
    bits = 8 if request.param == "spot5_triplet" else 12
    config = SceneConfig.small(configuration=request.param, markers=True, blunders=2, bits=bits)
    paths = simulated(config)
    with open(paths["truth"]) as f:
        truth = json.load(f)
    with open(paths["points"], newline="") as f:
        points = list(csv.DictReader(f))
    return config, paths, truth, points


def read(path):
    return gdal.Open(str(path)).ReadAsArray()


def centroid(image, col, row, scale_col, scale_row):
    """Intensity-weighted centroid of a marker around (col, row) (pixel centres at k + 0.5),
    background = median of the dark pad ring; scale = marker sigma in pixels."""
    jj, ii = np.meshgrid(
        np.arange(int(col - 6 * scale_col), int(col + 6 * scale_col) + 1),
        np.arange(int(row - 6 * scale_row), int(row + 6 * scale_row) + 1),
    )
    x, y = jj + 0.5, ii + 0.5
    d = np.hypot((x - col) / scale_col, (y - row) / scale_row)
    values = image[ii, jj].astype(float)
    weight = np.clip(values - np.median(values[(d > 3.8) & (d < 4.6)]), 0, None) * (d < 3.5)
    return (weight * x).sum() / weight.sum(), (weight * y).sum() / weight.sum()


def test_marker_centroids_match_the_truth_model(scene, figures):
    """Bright markers at the point candidates: detected centroids within 0.1 px of the truth
    model's ground_to_image (typically 0.01 px), and the CSV's true coordinates equal it."""
    config, paths, truth, points = scene
    assert len(points) >= 5
    worst = 0.0
    for name, info in truth["images"].items():
        image = read(paths["images"][name]["imagery"])
        model = sensors.load(paths["truth_metadata"][name])
        gsd_col = 5.0 if info["instrument"] == "HRG" else 10.0
        gsd_row = 10.0 if info["mission"] < 5 else 5.0
        for p in points:
            col, row = model.ground_to_image(float(p["lon"]), float(p["lat"]), float(p["h"]))
            assert (float(p[f"{name}_col"]), float(p[f"{name}_row"])) == pytest.approx((col, row), abs=2e-3)
            c, r = centroid(image, col, row, 10.0 / gsd_col, 10.0 / gsd_row)
            assert abs(c - col) < 0.1 and abs(r - row) < 0.1, (name, p["id"], c - col, r - row)
            worst = max(worst, abs(c - col), abs(r - row))
    figures.report("markers", len(points))
    figures.report("largest centroid error", worst, "px")


def test_round_trip_on_simulated_products(scene):
    """ground_to_image(image_to_ground(p, h), h) within 1e-4 px over the whole image, h -500..9000 m,
    for the supplied and the true orientation of every simulated image."""
    _, paths, _, _ = scene
    for name, product in paths["images"].items():
        for source in (product["metadata"], paths["truth_metadata"][name]):
            model = sensors.load(source)
            cols, rows = model.size
            c, r, h = np.meshgrid(np.linspace(0, cols, 25), np.linspace(0, rows, 25), [-500.0, 0.0, 3000.0, 9000.0])
            c2, r2 = model.ground_to_image(*model.image_to_ground(c, r, h), h)
            assert np.all(np.isfinite(c2)), source
            assert max(np.abs(c2 - c).max(), np.abs(r2 - r).max()) < 1e-4, source


def test_measurements_noise_and_blunders(scene):
    config, paths, truth, points = scene
    names = list(truth["images"])
    noise = 5 * config.measurement_sigma * np.sqrt(2)  # px: the measurement noise's to 5 sigma per coordinate
    dev, flagged = [], 0
    for p in points:
        for name in names:
            d = np.hypot(
                float(p[f"{name}_col_meas"]) - float(p[f"{name}_col"]),
                float(p[f"{name}_row_meas"]) - float(p[f"{name}_row"]),
            )
            if p[f"{name}_blunder"] == "1":
                flagged += 1
                assert 5.0 - noise <= d <= 20.0 + noise  # the simulator's 5-20 px blunder on top of the noise
            else:
                dev.append(d)
    assert flagged == config.blunders
    assert 0.1 < np.sqrt(np.mean(np.square(dev)) / 2) < 0.6  # sigma 0.3 px per coordinate


def test_footprint_rays_meet_the_dsm_where_the_truth_model_puts_them(scene):
    config, paths, truth, points = scene
    dsm = read_dem(paths["dsm"])
    for name, info in truth["images"].items():
        model = sensors.load(paths["truth_metadata"][name])
        fp = info["footprint"]
        col, row = np.array([f["col"] for f in fp]), np.array([f["row"] for f in fp])
        lon, lat, h = model.image_to_dem(col, row, dsm, samples=400)
        ray = geodetic_to_ecef(*np.array([[f["lon"], f["lat"], f["h"]] for f in fp]).T)
        assert np.max(np.linalg.norm(geodetic_to_ecef(lon, lat, h) - ray, axis=1)) < 0.05  # m
        c, r = model.ground_to_image(*np.array([[f["lon"], f["lat"], f["h"]] for f in fp]).T)
        assert np.max(np.hypot(c - col, r - row)) < 0.01


def test_supplied_orientation_is_off_by_about_30_m(scene):
    """Supplied vs truth on the ground (15-50 m, about 30 m on average), and supplied + the injected
    corrections reproduce the truth to a millimetre."""
    config, paths, truth, points = scene
    errors = []
    for name, info in truth["images"].items():
        true_model = sensors.load(paths["truth_metadata"][name])
        supplied = sensors.load(paths["images"][name]["metadata"])
        cols, rows = true_model.size
        c, r = (v.ravel() for v in np.meshgrid(np.linspace(0, cols, 5), np.linspace(0, rows, 5)))
        h = np.full(c.size, 400.0)
        truth_xyz = geodetic_to_ecef(*true_model.image_to_ground(c, r, h), h)
        d = np.linalg.norm(geodetic_to_ecef(*supplied.image_to_ground(c, r, h), h) - truth_xyz, axis=1)
        assert 8.0 < d.mean() < 60.0
        errors.append(d.mean())
        k = info["corrections"]
        supplied.orientation.corrections = Corrections(
            np.array(k["position"]), np.array(k["attitude"]), np.array(k["look"]), k["time_scale"]
        )
        corrected = geodetic_to_ecef(*supplied.image_to_ground(c, r, h), h)
        assert np.max(np.linalg.norm(corrected - truth_xyz, axis=1)) < 1e-3
    assert 15.0 < np.mean(errors) < 50.0


def test_classes_dsm_and_dtm_are_consistent(scene):
    config, paths, truth, points = scene
    classes, dsm, dtm = read(paths["classes"]), read(paths["dsm"]), read(paths["dtm"])
    objects = dsm - dtm
    on = np.isin(classes, (terrain.FOREST, terrain.CITY))
    assert np.all(objects[~on] == 0)
    assert np.percentile(objects[classes == terrain.FOREST], 5) > 5.0
    assert objects[classes == terrain.CITY].max() > 10.0 and np.mean(objects[classes == terrain.CITY] > 0) > 0.1
    assert {terrain.BARE, terrain.CROPS, terrain.FOREST, terrain.CITY} <= set(np.unique(classes))
    assert gdal.Open(paths["dsm"]).GetGeoTransform() == tuple(truth["grid"]["geotransform"])


def test_products_open_with_gdal_dimap_driver(scene):
    config, paths, truth, points = scene
    for name, product in paths["images"].items():
        ds = gdal.Open(product["metadata"])
        assert ds.GetDriver().ShortName == "DIMAP"
        assert (ds.RasterXSize, ds.RasterYSize) == tuple(truth["images"][name]["size"])
        pixels = ds.ReadAsArray()
        assert np.array_equal(pixels, read(product["imagery"]))
        assert pixels.dtype == (np.uint8 if config.bits == 8 else np.uint16) and pixels.min() > 0
        assert pixels.max() < 2**config.bits
    pairs = truth["base_to_height"]
    if config.configuration == "spot5_triplet":
        assert pairs["HRS1-HRS2"] == pytest.approx(0.8, abs=0.05)
    else:
        assert 0.4 < pairs["HRV1_A-HRV2_B"] < 0.6


def test_same_seed_same_bytes(tmp_path):
    config = SceneConfig.small(size_km=1.0, points=4)
    first = simulate_scene(config, tmp_path / "a")["folder"]
    second = simulate_scene(config, tmp_path / "b")["folder"]
    other = simulate_scene(SceneConfig.small(size_km=1.0, points=4, seed=2), tmp_path / "c")["folder"]
    files = sorted(os.path.relpath(os.path.join(d, f), first) for d, _, fs in os.walk(first) for f in fs)
    assert len(files) == 3 * 3 + 6  # 3 x (IMAGERY.TIF, METADATA.DIM, truth METADATA.DIM), truth.json, 5 rasters/CSV
    for rel in files:
        with open(os.path.join(first, rel), "rb") as a, open(os.path.join(second, rel), "rb") as b:
            assert a.read() == b.read(), rel
    with (
        open(os.path.join(first, "HRG", "IMAGERY.TIF"), "rb") as a,
        open(os.path.join(other, "HRG", "IMAGERY.TIF"), "rb") as c,
    ):
        assert a.read() != c.read()


def test_cancel_leaves_nothing(tmp_path):
    with pytest.raises(CancelledError):
        simulate_scene(SceneConfig.small(size_km=1.5, points=2), tmp_path / "out", Feedback(cancel_after=3))
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize(
    "overrides,message",
    [
        ({"configuration": "spot7"}, "configuration"),
        ({"size_km": 80.0}, "scene size"),
        ({"bits": 10}, "bits"),
        ({"roll_deg": (30.0,)}, "27"),
        ({"dates": ("2005-13-01",)}, "ISO date"),
        ({"centre_lon": -84.2, "centre_lat": None}, "centre_lat"),
        ({"centre_lon": -80.0, "centre_lat": 36.6}, "outside the source DEM"),
        ({"look_table": "/nonexistent/METADATA.DIM"}, "not a file"),
        ({"configuration": "spot14_pair", "roll_deg": "12"}, "needs 2 roll angle"),
        ({"configuration": "spot14_pair", "roll_deg": "12;-12"}, "comma-separated"),
    ],
)
def test_bad_parameters_raise_input_error(tmp_path, overrides, message):
    with pytest.raises(InputError, match=message):
        simulate_scene(SceneConfig.small(**overrides), tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_text_parameters_are_parsed():
    config = SceneConfig(configuration="spot14_pair", roll_deg="10, -14", dates="1999-07-10,1999-07-20").resolved()
    assert config.roll_deg == (10.0, -14.0) and config.dates == ("1999-07-10", "1999-07-20")


def test_look_table_from_a_real_dimap(tmp_path, spot5_dim, spot2_dim):
    """The real HRG table's shape (tilt and curvature of psi_x, non-linearity of psi_y, in
    detectors) and line period carry over to the simulated images."""
    paths = simulate_scene(SceneConfig.small(size_km=1.5, points=0, look_table=str(spot5_dim)), tmp_path / "s")
    real = sensors.load(spot5_dim).orientation
    truth = sensors.load(paths["truth_metadata"]["HRG"]).orientation
    assert truth.line_period == real.line_period
    s = (np.arange(truth.ncols) + 0.5) / truth.ncols
    real_dx = np.interp(s, (np.arange(real.ncols) + 0.5) / real.ncols, real.psi_x - real.psi_x.mean())
    np.testing.assert_allclose(truth.psi_x - truth.psi_x.mean(), real_dx - real_dx.mean(), atol=1e-9)
    with pytest.raises(InputError, match="SPOT 5 look-angle table"):
        simulate_scene(SceneConfig.small(look_table=str(spot2_dim)), tmp_path / "t")


def test_user_orthoimage_becomes_the_ground_reflectance(tmp_path):
    lon, lat = -84.19, 36.617
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 255, (400, 400)).astype(np.uint8)
    path = str(tmp_path / "ortho.tif")
    ds = gdal.GetDriverByName("GTiff").Create(path, 400, 400, 1, gdal.GDT_Byte)
    ds.SetGeoTransform((lon - 0.03, 0.00015, 0, lat + 0.03, 0, -0.00015))
    ds.SetProjection("EPSG:4326")
    ds.GetRasterBand(1).WriteArray(texture)
    ds = None
    paths = simulate_scene(
        SceneConfig.small(size_km=1.5, points=0, orthoimage=path, surface_objects=False), tmp_path / "s"
    )
    ortho = gdal.Open(paths["orthoimage"])
    gt = ortho.GetGeoTransform()
    warped = gdal.Warp(
        "",
        path,
        format="MEM",
        outputBounds=(gt[0], gt[3] + ortho.RasterYSize * gt[5], gt[0] + ortho.RasterXSize * gt[1], gt[3]),
        width=ortho.RasterXSize,
        height=ortho.RasterYSize,
        resampleAlg="bilinear",
    ).ReadAsArray()
    assert np.corrcoef(warped.ravel(), ortho.ReadAsArray().ravel())[0, 1] > 0.8
