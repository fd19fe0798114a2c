"""The pixels an Image masks (nodata value, GDAL mask band, saturation) against a plain numpy reference, and
touches_masked against a pixel-by-pixel loop."""

import pickle

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms.matching.imagery import Image, Smoothed, touches_masked


def write(path, data, gdal_type, nodata=None, valid=None, nbits=None):
    """A GeoTIFF of `data` with a nodata value, an internal per-dataset mask (`valid`, 0: invalid) and NBITS."""
    options = [f"NBITS={nbits}"] if nbits else []
    ds = gdal.GetDriverByName("GTiff").Create(str(path), data.shape[1], data.shape[0], 1, gdal_type, options)
    band = ds.GetRasterBand(1)
    band.WriteArray(data)
    if nodata is not None:
        band.SetNoDataValue(nodata)
    if valid is not None:
        band.CreateMaskBand(gdal.GMF_PER_DATASET)
        band.GetMaskBand().WriteArray(valid)
    ds = None
    return str(path)


def masked_reference(data, nodata=None, valid=None, saturation=None):
    """float32 `data` with NaN where it equals nodata, `valid` is 0 or it is at least `saturation`."""
    out = data.astype(np.float32)
    bad = np.zeros(data.shape, bool)
    if nodata is not None:
        bad |= data == nodata
    if valid is not None:
        bad |= valid == 0
    if saturation is not None:
        bad |= data >= saturation
    out[bad] = np.nan
    return out


@pytest.fixture(scope="module")
def pixels():
    rng = np.random.default_rng(5)
    data = rng.integers(0, 4096, (40, 50)).astype(np.uint16)
    data[3:6, 4:9] = 9  # nodata
    data[20:23, 30:33] = 4095  # saturated at 12 bits
    data[30, 10] = 65535  # saturated at 16 bits
    valid = np.full(data.shape, 255, np.uint8)
    valid[10:14, 40:47] = 0  # the mask band's invalid pixels
    return data, valid


def test_nodata_mask_band_and_saturation_against_numpy(pixels, tmp_path):
    data, valid = pixels
    plain = write(tmp_path / "plain.tif", data, gdal.GDT_UInt16, nodata=9, valid=valid)
    twelve = write(tmp_path / "twelve.tif", data & 4095, gdal.GDT_UInt16, nodata=9, nbits=12)
    cases = [
        (Image(plain), masked_reference(data, 9, valid)),
        (Image(plain, saturation=True), masked_reference(data, 9, valid, 65535)),
        (Image(plain, saturation=1000), masked_reference(data, 9, valid, 1000)),
        (Image(twelve, saturation=True), masked_reference(data & 4095, 9, None, 4095)),
    ]
    for image, expect in cases:
        got, x0, y0 = image.read(-2, 1, 60, 35)  # clipped to the image
        assert (x0, y0) == (0, 1)
        assert np.array_equal(got, expect[1:36, :], equal_nan=True)
    # saturation values: the data type's largest, or 2^NBITS - 1
    assert Image(plain, saturation=True).saturation == 65535 and Image(twelve, saturation=True).saturation == 4095
    assert Image(plain).saturation is None


def test_saturation_of_arrays_and_after_pickling(pixels):
    data, _ = pixels
    bytes_ = (data % 256).astype(np.uint8)
    image = Image(bytes_, saturation=True)
    assert image.saturation == 255
    again = pickle.loads(pickle.dumps(image))  # a worker reopens it with the same mask
    assert np.array_equal(again.read(0, 0, 50, 40)[0], masked_reference(bytes_, saturation=255), equal_nan=True)
    assert Image(data.astype(np.float32), saturation=True).saturation is None  # floating point: no saturation
    assert Image(data.astype(np.int16), saturation=True).saturation == 32767


def test_touches_masked_against_a_loop():
    rng = np.random.default_rng(7)
    img = rng.normal(size=(60, 70)).astype(np.float32)
    img[:, 20:][rng.random((60, 50)) < 0.004] = np.nan
    img[30:33, 5:8] = np.nan
    image = Image(img)
    x, y = rng.uniform(-5, 75, 400), rng.uniform(-5, 65, 400)
    x[:3], y[:3] = [6.5, 6.5, np.nan], [25.5, 25.4, 10.0]  # a window's edge just reaching the block, just not
    rx, ry = rng.uniform(0, 6, 400), rng.uniform(0, 6, 400)
    rx[:2], ry[:2] = 1.0, 5.0
    got = touches_masked(image, x, y, rx, ry)
    cols, rows = np.meshgrid(np.arange(70) + 0.5, np.arange(60) + 0.5)
    for k in range(len(x)):
        window = (np.abs(cols - x[k]) <= rx[k]) & (np.abs(rows - y[k]) <= ry[k])
        assert got[k] == bool(np.isnan(img[window]).any()), k
    assert got[0] and not got[1] and not got[2]
    # the same on a low-passed view: the NaN spread over the filter's support counts
    smooth = Smoothed(image, 1.0, 1.0)
    spread = np.isnan(smooth.read(0, 0, 70, 60)[0])
    got = touches_masked(smooth, x, y, rx, ry)
    for k in range(len(x)):
        window = (np.abs(cols - x[k]) <= rx[k]) & (np.abs(rows - y[k]) <= ry[k])
        assert got[k] == bool(spread[window].any()), k
