"""RpcModel against GDAL's RPC transformer on the real Pleiades images of the real test data: the
triplet's GeoTIFF RPC tags, and the Ventoux crops whose RPC comes from an OSSIM .geom describing
the full image. GDAL's reference for Ventoux gets the .geom's values, parsed here and shifted by
the crop's geotransform origin, in a MEM dataset (GDAL does not read .geom)."""

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.sensors.rpc_io import write_rpc_txt

gdal.UseExceptions()
pytestmark = pytest.mark.real

#: GDAL's image -> ground iteration stops at 0.1 px by default
GDAL_OPTIONS = ["METHOD=RPC", "RPC_PIXEL_ERROR_THRESHOLD=1e-9"]
KEYS = (
    "LINE_OFF",
    "SAMP_OFF",
    "LAT_OFF",
    "LONG_OFF",
    "HEIGHT_OFF",
    "LINE_SCALE",
    "SAMP_SCALE",
    "LAT_SCALE",
    "LONG_SCALE",
    "HEIGHT_SCALE",
)


def geom_reference(image):
    """A MEM dataset of the crop's size with the RPC of the .geom beside it, offsets moved into
    the crop by its geotransform origin."""
    kwl = dict(line.split(":", 1) for line in image.with_suffix(".geom").read_text().splitlines())
    kwl = {k.strip(): v.strip() for k, v in kwl.items()}
    assert kwl["polynomial_format"] == "B"  # RPC00B term order
    crop = gdal.Open(str(image))
    col0, _, _, row0, _, _ = crop.GetGeoTransform()
    fields = {k: kwl[k.lower()] for k in KEYS}
    fields["LINE_OFF"] = repr(float(fields["LINE_OFF"]) - row0)
    fields["SAMP_OFF"] = repr(float(fields["SAMP_OFF"]) - col0)
    for key in ("LINE_NUM", "LINE_DEN", "SAMP_NUM", "SAMP_DEN"):
        fields[key + "_COEFF"] = " ".join(kwl[f"{key.lower()}_coeff_{j:02d}"] for j in range(20))
    ds = gdal.GetDriverByName("MEM").Create("", crop.RasterXSize, crop.RasterYSize, 1)
    ds.SetMetadata(fields, "RPC")
    return ds


def dense_grid(model, n=41):
    """(col, row, h) over the raster, corners included, at 5 heights of the RPC's range."""
    c, r, h = np.meshgrid(
        np.linspace(0, model.size[0], n), np.linspace(0, model.size[1], n), np.linspace(*model.height_range, 5)
    )
    return c.ravel(), r.ravel(), h.ravel()


def max_errors_vs_gdal(model, ds):
    """Max pixel differences (image -> ground, ground -> image) between the model and GDAL."""
    transformer = gdal.Transformer(ds, None, GDAL_OPTIONS)
    col, row, h = dense_grid(model)
    ground, ok = transformer.TransformPoints(0, np.column_stack([col, row, h]))
    assert all(ok)
    ground = np.array(ground)
    lon, lat = model.image_to_ground(col, row, h)
    # ground differences in pixels, through d(col, row)/d(lon, lat)
    jac = model.partials(lon, lat, h)["d_ground"][:, :, :2]
    to_ground_px = np.abs(np.einsum("nij,nj->ni", jac, ground[:, :2] - np.column_stack([lon, lat]))).max()
    image, ok = transformer.TransformPoints(1, ground)
    assert all(ok)
    image = np.array(image)
    c2, r2 = model.ground_to_image(ground[:, 0], ground[:, 1], ground[:, 2])
    to_image_px = max(np.abs(c2 - image[:, 0]).max(), np.abs(r2 - image[:, 1]).max())
    return to_ground_px, to_image_px


def test_triplet_matches_gdal(triplet_image):
    model = sensors.load(triplet_image)
    ds = gdal.Open(str(triplet_image))
    assert model.size == (ds.RasterXSize, ds.RasterYSize) and model.offset == (0.0, 0.0)
    errors = max_errors_vs_gdal(model, ds)
    assert max(errors) < 0.01, errors


def test_ventoux_geom_with_crop_offset_matches_gdal(ventoux_image):
    model = sensors.load(ventoux_image.with_suffix(".geom"))
    reference = geom_reference(ventoux_image)
    crop = gdal.Open(str(ventoux_image))
    assert model.size == (crop.RasterXSize, crop.RasterYSize)
    assert model.offset == (crop.GetGeoTransform()[0], crop.GetGeoTransform()[3])
    errors = max_errors_vs_gdal(model, reference)
    assert max(errors) < 0.01, errors


def assert_round_trip(model):
    col, row, h = dense_grid(model)
    c2, r2 = model.ground_to_image(*model.image_to_ground(col, row, h), h)
    assert max(np.abs(c2 - col).max(), np.abs(r2 - row).max()) < 1e-4


def assert_written_rpc_txt_reads_back(model, folder):
    """_RPC.TXT beside a raster of the model's size: GDAL and our reader give the model's mapping."""
    raster = folder / "copy.tif"
    ds = gdal.GetDriverByName("GTiff").Create(str(raster), *model.size, 1, gdal.GDT_Byte)
    del ds  # closes the file
    write_rpc_txt(model, folder / "copy_RPC.TXT")
    col, row, h = dense_grid(model, 11)
    lon, lat = model.image_to_ground(col, row, h)
    ds = gdal.Open(str(raster))  # kept alive while its transformer is used
    image, ok = gdal.Transformer(ds, None, GDAL_OPTIONS).TransformPoints(1, np.column_stack([lon, lat, h]))
    assert all(ok)
    assert np.abs(np.array(image)[:, :2] - np.column_stack([col, row])).max() < 1e-6
    reread = sensors.load(folder / "copy_RPC.TXT")
    assert reread.size == model.size
    c2, r2 = reread.ground_to_image(lon, lat, h)
    assert max(np.abs(c2 - col).max(), np.abs(r2 - row).max()) < 1e-6


def test_round_trip_triplet(triplet_image):
    assert_round_trip(sensors.load(triplet_image))


def test_round_trip_ventoux(ventoux_image):
    assert_round_trip(sensors.load(ventoux_image))


def test_write_read_triplet(triplet_image, tmp_path):
    assert_written_rpc_txt_reads_back(sensors.load(triplet_image), tmp_path)


def test_write_read_ventoux_crop(ventoux_image, tmp_path):
    assert_written_rpc_txt_reads_back(sensors.load(ventoux_image), tmp_path)
