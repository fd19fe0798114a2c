"""RpcModel on a synthetic RPC00B: kernels against a plain numpy reference, analytic partials
against finite differences, the iterative inverse, GDAL's pixel convention, crop offsets, and the
readers and writers (GeoTIFF tags, _RPC.TXT, .RPB, OSSIM .geom in formats A and B)."""

import math

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.errors import GeometryError, MetadataError
from pushbroom.algorithms.sensors.rpc import RpcCoefficients, RpcModel, _poly, rpc_terms
from pushbroom.algorithms.sensors.rpc_io import write_rpb, write_rpc_txt
from tests.helpers.rpc_synthetic import (
    SCALARS,
    geom_text,
    numpy_ground_to_image,
    synthetic_coefficients,
    synthetic_fields,
    write_raster,
)

gdal.UseExceptions()

CROP = (19000.0, 20500.0)  # top-left corner of the crop in the full image the RPC describes
SIZE = (1000, 800)


@pytest.fixture
def fields():
    return synthetic_fields()


@pytest.fixture
def model():
    return RpcModel(synthetic_coefficients(), SIZE, CROP, "synthetic crop")


def ground_points(n=400, seed=1):
    """Random ground points over the RPC's whole normalisation domain."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1.0, 1.0, (3, n))
    return (
        SCALARS["LONG_OFF"] + u[0] * SCALARS["LONG_SCALE"],
        SCALARS["LAT_OFF"] + u[1] * SCALARS["LAT_SCALE"],
        SCALARS["HEIGHT_OFF"] + u[2] * SCALARS["HEIGHT_SCALE"],
    )


def image_grid(model, n=11):
    """(col, row, h) of an n x n grid over the model's raster, borders included, at 3 heights."""
    return np.meshgrid(
        np.linspace(0, model.size[0], n), np.linspace(0, model.size[1], n), np.linspace(*model.height_range, 3)
    )


def test_ground_to_image_matches_numpy_reference(model, fields):
    lon, lat, h = ground_points()
    col, row = model.ground_to_image(lon, lat, h)
    ref_col, ref_row = numpy_ground_to_image(fields, lon, lat, h, *CROP)
    assert np.abs(col - ref_col).max() < 1e-8
    assert np.abs(row - ref_row).max() < 1e-8


def test_partials_match_central_differences(model):
    lon, lat, h = ground_points(50)
    jac = model.partials(lon, lat, h)["d_ground"]
    steps = (1e-6, 1e-6, 0.1)  # deg, deg, m
    for k, step in enumerate(steps):
        plus = [lon, lat, h]
        minus = [lon, lat, h]
        plus[k] = plus[k] + step
        minus[k] = minus[k] - step
        fd = (np.array(model.ground_to_image(*plus)) - np.array(model.ground_to_image(*minus))) / (2 * step)
        assert np.abs(jac[:, :, k] - fd.T).max() < 1e-6 * np.abs(fd).max()


def test_image_to_ground_inverts_ground_to_image_over_the_whole_domain():
    full = RpcModel(synthetic_coefficients())
    lon, lat, h = ground_points()
    col, row = full.ground_to_image(lon, lat, h)
    lon2, lat2 = full.image_to_ground(col, row, h)
    assert np.abs(lon2 - lon).max() < 1e-10
    assert np.abs(lat2 - lat).max() < 1e-10
    c, r, hh = image_grid(full)
    c2, r2 = full.ground_to_image(*full.image_to_ground(c, r, hh), hh)
    assert max(np.abs(c2 - c).max(), np.abs(r2 - r).max()) < 1e-6


def test_scalars_give_scalars_and_arrays_broadcast(model):
    lon, lat = model.image_to_ground(10.0, 20.0, 500.0)
    assert isinstance(lon, float) and isinstance(lat, float)
    col, row = model.ground_to_image(lon, lat, 500.0)
    assert isinstance(col, float) and abs(col - 10.0) < 1e-6 and abs(row - 20.0) < 1e-6
    cols = np.arange(6.0).reshape(2, 3)
    lon, lat = model.image_to_ground(cols, 5.0, 500.0)
    assert lon.shape == lat.shape == (2, 3)
    assert model.partials(lon, lat, 500.0)["d_ground"].shape == (2, 3, 2, 3)


def test_nan_in_gives_nan_out(model):
    lon, lat = model.image_to_ground([np.nan, 5.0], [1.0, 5.0], 500.0)
    assert np.isnan(lon[0]) and np.isnan(lat[0]) and np.isfinite(lon[1])


def test_a_degenerate_rpc_is_refused_where_read(fields):
    """Column and row both from longitude alone: before, the first image point met "a singular Jacobian"."""
    linear_in_lon = [0.0, 1.0] + [0.0] * 18
    fields.update(LINE_NUM_COEFF=linear_in_lon, SAMP_NUM_COEFF=linear_in_lon)
    with pytest.raises(MetadataError, match="degenerate: the image column and row change along one ground direction"):
        RpcCoefficients.from_fields(fields, "degenerate")


def test_an_image_point_without_a_ground_point_raises_geometry_error(fields):
    model = RpcModel(RpcCoefficients.from_fields(fields, "synthetic"))
    with pytest.raises(GeometryError, match="no ground point found for 1 of 1"):
        model.image_to_ground(1e9, 1e9, 1000.0)  # far beyond the image: the cubics have no answer there


@pytest.mark.parametrize("crop", [(0.0, 0.0), CROP])
def test_pixel_convention_is_gdals_and_rpc00b_centre_plus_half(fields, crop):
    """RPC00B's image offset is the first pixel's centre at (0, 0); GDAL (and this model) put the
    first pixel's corner at (0, 0), i.e. add 0.5. Measured on a point that the RPC maps to its
    image offset exactly: the ground offsets, with zero constant numerator terms."""
    fields["LINE_NUM_COEFF"][0] = fields["SAMP_NUM_COEFF"][0] = 0.0
    model = RpcModel(RpcCoefficients.from_fields(fields), offset=crop)
    ground = (SCALARS["LONG_OFF"], SCALARS["LAT_OFF"], SCALARS["HEIGHT_OFF"])
    expected = (SCALARS["SAMP_OFF"] + 0.5 - crop[0], SCALARS["LINE_OFF"] + 0.5 - crop[1])
    assert model.ground_to_image(*ground) == pytest.approx(expected, abs=1e-9)
    ds = gdal.GetDriverByName("MEM").Create("", 10, 10, 1)
    ds.SetMetadata(model.to_fields(), "RPC")
    ok, gdal_image = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoint(1, *ground)
    assert ok and gdal_image[:2] == pytest.approx(expected, abs=1e-9)


def test_crop_offset_shifts_image_coordinates_only(model):
    full = RpcModel(model.coefficients)
    lon, lat, h = ground_points(20)
    col, row = model.ground_to_image(lon, lat, h)
    full_col, full_row = full.ground_to_image(lon, lat, h)
    assert np.abs(full_col - CROP[0] - col).max() < 1e-9
    assert np.abs(full_row - CROP[1] - row).max() < 1e-9


def test_size_without_raster_is_the_normalisation_range():
    c = synthetic_coefficients()
    assert RpcModel(c).size == (math.ceil(c.samp_off + 0.5 + c.samp_scale), math.ceil(c.line_off + 0.5 + c.line_scale))
    assert RpcModel(c, offset=CROP).size == (
        math.ceil(c.samp_off + 0.5 + c.samp_scale - CROP[0]),
        math.ceil(c.line_off + 0.5 + c.line_scale - CROP[1]),
    )


def test_coefficients_are_exposed_read_only(model, fields):
    c = model.coefficients
    assert np.array_equal(c.samp_num, fields["SAMP_NUM_COEFF"]) and c.line_off == SCALARS["LINE_OFF"]
    with pytest.raises(ValueError):
        c.line_num[0] = 1.0


def assert_same_mapping(a, b, tol=1e-6):
    lon, lat, h = ground_points(200)
    ca, ra = a.ground_to_image(lon, lat, h)
    cb, rb = b.ground_to_image(lon, lat, h)
    assert max(np.abs(ca - cb).max(), np.abs(ra - rb).max()) < tol


def gdal_ground_to_image(raster, lon, lat, h):
    """GDAL's RPC transformer, on the RPC GDAL itself finds for `raster`."""
    ds = gdal.Open(str(raster))
    assert ds.GetMetadata("RPC"), f"GDAL found no RPC for {raster}"
    out, ok = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.column_stack([lon, lat, h]))
    assert all(ok)
    return np.array(out)[:, 0], np.array(out)[:, 1]


@pytest.mark.parametrize("writer, name", [(write_rpc_txt, "crop_RPC.TXT"), (write_rpb, "crop.RPB")])
def test_written_rpc_file_reads_back_through_gdal_and_our_readers(tmp_path, model, writer, name):
    raster = write_raster(tmp_path / "crop.tif", SIZE)
    writer(model, tmp_path / name)
    lon, lat, h = ground_points(200)
    col, row = model.ground_to_image(lon, lat, h)
    gdal_col, gdal_row = gdal_ground_to_image(raster, lon, lat, h)
    assert max(np.abs(gdal_col - col).max(), np.abs(gdal_row - row).max()) < 1e-6
    for loaded in (sensors.load(tmp_path / name), sensors.load(raster)):
        assert isinstance(loaded, RpcModel) and loaded.size == SIZE and loaded.offset == (0.0, 0.0)
        assert_same_mapping(loaded, model)
    assert not [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left


def test_rpb_without_error_fields(tmp_path, model):
    write_rpb(model, tmp_path / "e.RPB")
    text = (tmp_path / "e.RPB").read_text()
    (tmp_path / "e.RPB").write_text(text.replace("\terrBias = 0.0;\n", "").replace("\terrRand = 0.0;\n", ""))
    assert_same_mapping(RpcModel.from_rpc_file(tmp_path / "e.RPB"), model)


def test_rpc_file_without_raster_beside_it_estimates_the_size(tmp_path, model):
    write_rpc_txt(model, tmp_path / "lone_RPC.TXT")
    loaded = RpcModel.from_rpc_file(tmp_path / "lone_RPC.TXT")
    assert loaded.size == RpcModel(loaded.coefficients).size
    assert_same_mapping(loaded, model)


def test_geotiff_rpc_tags(tmp_path, fields):
    raster = write_raster(tmp_path / "tagged.tif", SIZE, rpc=fields)
    loaded = sensors.load(raster)
    assert loaded.size == SIZE and loaded.offset == (0.0, 0.0)
    assert_same_mapping(loaded, RpcModel(synthetic_coefficients()), 1e-9)


def test_geom_beside_a_crop_takes_its_offset_and_size(tmp_path, fields, model):
    (tmp_path / "left.geom").write_text(geom_text(fields))
    raster = write_raster(tmp_path / "left.tif", SIZE, geotransform=(CROP[0], 1, 0, CROP[1], 0, 1))
    for loaded in (
        sensors.load(tmp_path / "left.geom"),
        sensors.load(raster),
        RpcModel.from_geom(tmp_path / "left.geom", image=raster),
    ):
        assert loaded.size == SIZE and loaded.offset == CROP
        assert_same_mapping(loaded, model, 1e-9)


def test_orientation_files_are_not_redirected_to_a_metadata_dim_beside_them(tmp_path, fields, model):
    """A folder holding a SPOT METADATA.DIM and a Pleiades crop with its .geom: the .geom (given,
    or found beside its raster) is the crop's orientation; the folder itself is the SPOT product."""
    from pushbroom.algorithms.sensors.dimap_writer import write_dimap
    from tests.helpers.spot_synthetic import synthetic_orientation

    write_dimap(tmp_path / "METADATA.DIM", synthetic_orientation(ncols=40))
    (tmp_path / "left.geom").write_text(geom_text(fields))
    raster = write_raster(tmp_path / "left.tif", SIZE, geotransform=(CROP[0], 1, 0, CROP[1], 0, 1))
    for path in (tmp_path / "left.geom", raster):
        loaded = sensors.load(path)
        assert isinstance(loaded, RpcModel) and loaded.offset == CROP
        assert sensors.orientation_source(path) == str(tmp_path / "left.geom")
    assert sensors.load(tmp_path).size == (40, 200)


def test_geom_alone_describes_the_full_image(tmp_path, fields):
    (tmp_path / "full.geom").write_text(geom_text(fields, size=(39182, 41801)))
    loaded = sensors.load(tmp_path / "full.geom")
    assert loaded.size == (39182, 41801) and loaded.offset == (0.0, 0.0)
    assert_same_mapping(loaded, RpcModel(synthetic_coefficients()), 1e-9)


def test_geom_polynomial_format_a_is_reordered_to_rpc00b(tmp_path, fields):
    (tmp_path / "a.geom").write_text(geom_text(fields, polynomial_format="A"))
    loaded = RpcModel.from_geom(tmp_path / "a.geom")
    assert np.array_equal(loaded.coefficients.line_num, fields["LINE_NUM_COEFF"])
    assert_same_mapping(loaded, RpcModel(synthetic_coefficients()), 1e-9)


def test_written_crop_rpc_gives_gdal_the_crop_mapping(tmp_path, model):
    """A crop model written beside the crop raster: GDAL reads LINE_OFF/SAMP_OFF of the crop."""
    raster = write_raster(tmp_path / "c.tif", SIZE)
    write_rpc_txt(model, tmp_path / "c_RPC.TXT")
    fields = gdal.Open(str(raster)).GetMetadata("RPC")
    assert float(fields["SAMP_OFF"]) == SCALARS["SAMP_OFF"] - CROP[0]
    assert float(fields["LINE_OFF"]) == SCALARS["LINE_OFF"] - CROP[1]


BIAS = np.array([1.5, 0.8, -0.4, -2.0, 0.3, 1.1])  # px, px per 1000 px


def test_bias_is_an_affine_image_correction_with_exact_partials(model, tmp_path):
    """col' = col + A0 + A1 u + A2 v (row' likewise), u, v = (col, row) about the raster centre /
    1000; image_to_ground inverts it; partials through it (ground) and of it (d_corrections)
    agree with central differences; the model file keeps it and RPC writers refuse it."""
    from pushbroom.algorithms.errors import InputError
    from pushbroom.algorithms.sensors.model_file import save_model_file

    biased = RpcModel(model.coefficients, model.size, model.offset, "biased", bias=BIAS)
    lon, lat, h = ground_points(60)
    col, row = model.ground_to_image(lon, lat, h)
    u, v = (col - model.size[0] / 2) / 1000, (row - model.size[1] / 2) / 1000
    c2, r2 = biased.ground_to_image(lon, lat, h)
    np.testing.assert_allclose(c2, col + BIAS[0] + BIAS[1] * u + BIAS[2] * v, atol=1e-9)
    np.testing.assert_allclose(r2, row + BIAS[3] + BIAS[4] * u + BIAS[5] * v, atol=1e-9)
    back = biased.image_to_ground(c2, r2, h)
    np.testing.assert_allclose(back, (lon, lat), atol=1e-10)
    p = biased.partials(lon, lat, h)
    np.testing.assert_allclose((p["col"], p["row"]), (c2, r2), atol=1e-9)
    for k, step in enumerate((1e-6, 1e-6, 0.1)):
        plus, minus = [lon, lat, h], [lon, lat, h]
        plus[k], minus[k] = plus[k] + step, minus[k] - step
        fd = (np.array(biased.ground_to_image(*plus)) - np.array(biased.ground_to_image(*minus))) / (2 * step)
        assert np.abs(p["d_ground"][:, :, k] - fd.T).max() < 1e-6 * np.abs(fd).max()
    for k in range(6):
        e = np.zeros(6)
        e[k] = 1e-3
        plus = np.array(
            RpcModel(model.coefficients, model.size, model.offset, bias=BIAS + e).ground_to_image(lon, lat, h)
        )
        minus = np.array(
            RpcModel(model.coefficients, model.size, model.offset, bias=BIAS - e).ground_to_image(lon, lat, h)
        )
        np.testing.assert_allclose(p["d_corrections"][:, :, k], ((plus - minus) / 2e-3).T, atol=1e-9)
    path = tmp_path / "m.pbmodel.json"
    save_model_file(biased, path)
    np.testing.assert_array_equal(sensors.load(str(path)).bias, BIAS)
    with pytest.raises(InputError, match="fit new RPCs"):
        write_rpc_txt(biased, tmp_path / "x_RPC.TXT")


def test_rpc_terms_is_the_design_matrix_of_the_kernel_polynomial():
    rng = np.random.default_rng(3)
    c = rng.normal(size=20)
    x, y, z = rng.uniform(-1.2, 1.2, (3, 50))
    np.testing.assert_allclose(rpc_terms(x, y, z) @ c, [_poly(c, *p) for p in zip(x, y, z)], rtol=1e-13, atol=1e-13)


def test_image_to_ground_or_nan_marks_only_the_failing_points(model):
    """Where the Newton iteration fails for some points, image_to_ground raises for the batch and
    image_to_ground_or_nan gives NaN for those points only, the others as image_to_ground."""
    col, row, h = (v.ravel() for v in image_grid(model, 5))
    good = model.image_to_ground(col, row, h)
    bad_col, bad_row = np.append(col, 1e9), np.append(row, 1e9)
    with pytest.raises(GeometryError):
        model.image_to_ground(bad_col, bad_row, np.append(h, h[0]))
    lon, lat = model.image_to_ground_or_nan(bad_col, bad_row, np.append(h, h[0]))
    assert np.isnan(lon[-1]) and np.isnan(lat[-1])
    np.testing.assert_array_equal(lon[:-1], good[0])
