"""RPC fitting (algorithms/sensors/rpc_fit.py): fitted to simulated SPOT 5 and SPOT 1-4 scenes and
checked against the rigorous model at independent points, through GDAL's RPC transformer on the
written _RPC.TXT, exact recovery of a known rational RPC, the polynomial fallback near a pole, and
clear errors on degenerate input."""
import pathlib
import shutil

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.sensors.base import SensorModel
from pushbroom.algorithms.sensors.rpc import RpcCoefficients, RpcModel
from pushbroom.algorithms.sensors.rpc_fit import (default_height_range, fit_rpc, raster_reads, report_html,
                                                  rpc_txt_path, write_fitted_rpc)
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene

gdal.UseExceptions()

SCENES = {"spot5_triplet": ("HRG", "HRS1", "HRS2"), "spot14_pair": ("HRV1_A", "HRV2_B")}
TOLERANCE_PX = 0.01      # fitted RPC vs rigorous model
GDAL_TOLERANCE_PX = 0.02  # GDAL's RPC transformer on the written file vs rigorous model


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """Both simulated scenes: {configuration: simulate_scene paths}."""
    folder = tmp_path_factory.mktemp("rpc_fit")
    return {c: simulate_scene(SceneConfig.small(configuration=c), folder / c) for c in SCENES}


def scene_model(scenes, configuration, name):
    """(supplied sensor model, cube height range = DSM range widened, paths) of one simulated image."""
    paths = scenes[configuration]
    return (sensors.load(paths["images"][name]["metadata"]),
            default_height_range(Dem.from_file(paths["dsm"]).height_range), paths)


def random_image_points(model, height_range, n=500, seed=3):
    rng = np.random.default_rng(seed)
    cols, rows = model.size
    return rng.uniform(0, cols, n), rng.uniform(0, rows, n), rng.uniform(*height_range, n)


IMAGES = [(c, n) for c, names in SCENES.items() for n in names]


@pytest.mark.parametrize("configuration, name", IMAGES)
def test_fitted_rpc_reproduces_the_rigorous_model(scenes, configuration, name):
    model, height_range, _ = scene_model(scenes, configuration, name)
    rpc, report = fit_rpc(model, height_range)
    print(f"{name}: {report.summary()}")
    assert isinstance(rpc, RpcModel) and rpc.size == model.size and not report.fallback
    assert report.cube_points == 11 ** 3 and report.validation_points == 20 ** 3
    assert report.max_error < TOLERANCE_PX
    # independent random points: rigorous image -> ground, fitted RPC ground -> image
    col, row, h = random_image_points(model, height_range)
    lon, lat = model.image_to_ground(col, row, h)
    rc, rr = rpc.ground_to_image(lon, lat, h)
    mc, mr = model.ground_to_image(lon, lat, h)
    err = max(np.abs(rc - mc).max(), np.abs(rr - mr).max())
    print(f"{name}: max |RPC - rigorous| at 500 random points {err:.2e} px")
    assert err < TOLERANCE_PX
    # the report's validation figures are what the RPC does between the cube points
    assert err <= 2.0 * max(report.validation_col.max, report.validation_row.max)


@pytest.mark.parametrize("configuration, name", [("spot5_triplet", "HRS1"), ("spot14_pair", "HRV1_A")])
def test_gdal_reads_the_written_rpc_txt_beside_the_raster(scenes, configuration, name, tmp_path):
    """Beside IMAGERY.TIF in a copy of the DIMAP product folder (GDAL's own <stem>_RPC.TXT naming):
    GDAL prefers it to the DIMAP metadata, and its RPC transformer matches the rigorous model both
    ways."""
    model, height_range, paths = scene_model(scenes, configuration, name)
    product = shutil.copytree(pathlib.Path(paths["images"][name]["imagery"]).parent, tmp_path / name)
    raster = product / "IMAGERY.TIF"
    rpc, _ = fit_rpc(model, height_range)
    path = write_fitted_rpc(rpc, rpc_txt_path(raster))
    assert path == str(product / "IMAGERY_RPC.TXT")
    assert raster_reads(raster, rpc)
    ds = gdal.Open(str(raster))
    col, row, h = random_image_points(model, height_range, 300, seed=7)
    lon, lat = model.image_to_ground(col, row, h)
    out, ok = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.column_stack([lon, lat, h]))
    out = np.array(out)
    assert all(ok)
    ground_to_image = max(np.abs(out[:, 0] - col).max(), np.abs(out[:, 1] - row).max())
    transformer = gdal.Transformer(ds, None, ["METHOD=RPC", "RPC_PIXEL_ERROR_THRESHOLD=1e-6"])
    out, ok = transformer.TransformPoints(0, np.column_stack([col, row, h]))
    out = np.array(out)
    assert all(ok)
    back_col, back_row = model.ground_to_image(out[:, 0], out[:, 1], h)
    image_to_ground = max(np.abs(back_col - col).max(), np.abs(back_row - row).max())
    print(f"{name}: GDAL RPC vs rigorous: ground->image {ground_to_image:.2e} px, image->ground "
          f"{image_to_ground:.2e} px")
    assert ground_to_image < GDAL_TOLERANCE_PX and image_to_ground < GDAL_TOLERANCE_PX
    # and the project's own reader of the file alone: same size (the normalisation spans the image)
    loaded = sensors.load(path)
    assert isinstance(loaded, RpcModel) and loaded.size == model.size
    assert np.allclose(loaded.ground_to_image(lon, lat, h), rpc.ground_to_image(lon, lat, h), rtol=0, atol=1e-9)


def known_rpc(samp_den, size=None):
    """A known RPC00B as the 'rigorous' model: col = (L + 0.05 H + 0.02 L P) / samp_den . t and
    row = (P - 0.03 H) / (1 + 0.01 L) over 0.2 x 0.2 degrees and 0 .. 2000 m."""
    def coef(**terms):
        c = np.zeros(20)
        for k, v in terms.items():
            c[int(k[1:])] = v
        return c
    fields = {"LINE_OFF": 4999.5, "SAMP_OFF": 4999.5, "LAT_OFF": 44.0, "LONG_OFF": 5.0, "HEIGHT_OFF": 1000.0,
              "LINE_SCALE": 5000.0, "SAMP_SCALE": 5000.0, "LAT_SCALE": 0.1, "LONG_SCALE": 0.1,
              "HEIGHT_SCALE": 1000.0, "SAMP_NUM_COEFF": coef(t1=1.0, t3=0.05, t4=0.02),
              "SAMP_DEN_COEFF": np.asarray(samp_den, float), "LINE_NUM_COEFF": coef(t2=1.0, t3=-0.03),
              "LINE_DEN_COEFF": coef(t0=1.0, t1=0.01)}
    return RpcModel(RpcCoefficients.from_fields(fields, "known"), size=size)


def test_a_rational_rpc_is_recovered_exactly():
    """The iteratively reweighted fit recovers a truly rational mapping (denominators 1 + 0.3 L -
    0.1 P + 0.05 H) to 1e-6 px, which no cubic polynomial can (checked: more than 1 px)."""
    model = known_rpc([1.0, 0.3, -0.1, 0.05] + [0.0] * 16)
    rpc, report = fit_rpc(model, (0.0, 2000.0))
    print(f"known rational RPC: {report.summary()}; {report.iterations} reweighting iterations")
    assert not report.fallback and report.max_error < 1e-6
    lon, lat = model.image_to_ground(*random_image_points(model, (0.0, 2000.0))[:2], 1234.0)
    assert np.allclose(rpc.ground_to_image(lon, lat, 1234.0), model.ground_to_image(lon, lat, 1234.0),
                       rtol=0, atol=1e-6)
    t = rpc.coefficients
    ratio = np.array(t.samp_den[1:4]) / np.array(model.coefficients.samp_den[1:4])
    assert ratio == pytest.approx([1.0] * 3, rel=1e-4)   # same normalisation here: the same denominator


def test_a_denominator_near_zero_falls_back_to_a_cubic_polynomial():
    """Column = L / (1 + 0.9 L) over the image: the fitted denominator would fall to 0.05 of its
    largest value, so the column is fitted as a plain cubic (large error, reported); the row stays
    rational and exact."""
    model = known_rpc([1.0, 0.9] + [0.0] * 18)
    rpc, report = fit_rpc(model, (0.0, 2000.0))
    print(f"near-pole RPC: {report.summary()}")
    assert report.fallback and report.polynomial == ("col",)
    assert list(rpc.coefficients.samp_den) == [1.0] + [0.0] * 19
    assert np.count_nonzero(rpc.coefficients.line_den[1:]) > 0
    assert report.validation_row.max < 1e-6 and report.validation_col.max > 1.0
    assert "cubic polynomial for col" in report.summary()
    # the reported errors are the RPC's: recomputed at the validation grid's first corner point
    col, row = 0.25 * model.size[0] / 10, 0.25 * model.size[1] / 10
    lon, lat = model.image_to_ground(col, row, 50.0)
    assert abs(rpc.ground_to_image(lon, lat, 50.0)[0] - col) <= report.validation_col.max


class NanModel(SensorModel):
    """A model without ground positions in the right half of its image."""
    size = (100, 80)

    def image_to_ground(self, col, row, h):
        col, row = np.asarray(col, float), np.asarray(row, float)
        return np.where(col > 50, np.nan, 5.0 + 1e-4 * col), 44.0 - 1e-4 * row + 0.0 * np.asarray(h)


@pytest.mark.parametrize("height_range, match", [((500.0, 500.0), "height range 500.0 .. 500.0"),
                                                 ((800.0, 100.0), "highest height above"),
                                                 ((0.0, np.nan), "finite range")])
def test_degenerate_height_ranges_are_input_errors(height_range, match):
    with pytest.raises(InputError, match=match):
        fit_rpc(known_rpc([1.0] + [0.0] * 19), height_range)


def test_a_model_returning_nan_is_an_input_error():
    with pytest.raises(InputError, match=r"no ground position for 605 of 1331 image points"):
        fit_rpc(NanModel(), (0.0, 100.0))


def test_a_model_that_does_not_converge_is_an_input_error():
    """An RPC asked beyond its domain raises GeometryError; the fit reports it as input."""
    model = known_rpc([1.0, 0.9] + [0.0] * 18, size=(40000, 10000))
    with pytest.raises(InputError, match="no ground position over the whole image"):
        fit_rpc(model, (0.0, 2000.0))


def test_too_small_a_grid_is_an_input_error():
    with pytest.raises(InputError, match="at least 4"):
        fit_rpc(known_rpc([1.0] + [0.0] * 19), (0.0, 100.0), grid=(11, 11, 3))


def test_cancel_raises():
    class Cancelled:
        def isCanceled(self):  # noqa: N802 (QGIS API)
            return True

    with pytest.raises(CancelledError):
        fit_rpc(known_rpc([1.0] + [0.0] * 19), (0.0, 100.0), feedback=Cancelled())


def test_files_and_report(tmp_path):
    raster = tmp_path / "scene.tif"
    assert rpc_txt_path(raster) == str(tmp_path / "scene_RPC.TXT")
    assert rpc_txt_path(raster, tmp_path / "out", "HRG") == str(tmp_path / "out" / "HRG_RPC.TXT")
    assert default_height_range((100.0, 300.0)) == (0.0, 400.0)
    assert default_height_range((0.0, 3000.0)) == (-300.0, 3300.0)
    rpc, report = fit_rpc(known_rpc([1.0] + [0.0] * 19), (0.0, 100.0))
    path = write_fitted_rpc(rpc, tmp_path / "scene_RPC.TXT")
    with pytest.raises(InputError, match="exists already"):
        write_fitted_rpc(rpc, path)
    assert not raster_reads(raster, rpc)   # no raster there
    page = report_html([("A<1>", path, report)])
    assert "<td>A&lt;1&gt;</td>" in page and f"{report.validation_col.max:.2e}" in page


@pytest.mark.real
@pytest.mark.parametrize("fixture", ["spot5_dim", "spot2_dim"])
def test_real_spot_scene_with_the_papers_cube(fixture, request):
    """A full real SPOT scene, the paper's cube (11 x 11 image grid, -250 .. 2250 m in 250 m steps):
    sub-pixel, though not 0.01 px: the attitude samples and look-angle tables wiggle more than a
    cubic follows (errors printed)."""
    model = sensors.load(request.getfixturevalue(fixture))
    rpc, report = fit_rpc(model, (-250.0, 2250.0))
    print(f"{fixture} {model.size}: {report.summary()}")
    assert report.max_error < 0.5
