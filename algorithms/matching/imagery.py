"""Windowed access to one band of a raster, so the matchers' memory is bounded by the tile size,
not the scene size.

Coordinates are GDAL's: a window read at (x0, y0) returns array pixel (i, j) with its centre at
image position (x0 + j + 0.5, y0 + i + 0.5).

Masked pixels come back as NaN, which the matchers treat as "cannot match here" (a NaN correlation fails
every acceptance test; a census window with a NaN has no code): the band's nodata value, the pixels its
GDAL mask band (an internal or .msk mask, an alpha band) marks invalid, and, where an Image is opened with
`saturation`, the saturated pixels (at or above the saturation value: their grey values say nothing of the
ground, and the edge of a saturated patch is a texture of the sensor, not of the scene). The mask is applied
here, once, where a window is read: everything derived from an Image (Smoothed, Window, epipolar images)
inherits it, and `touches_masked` tells which matching windows reach a masked pixel."""

import math
import os
import threading

import numpy as np

from ..errors import InputError


def clipped(size, x0, y0, cols, rows):
    """(xa, ya, xb, yb): the window of `cols` x `rows` px at (x0, y0) clipped to an image of `size`
    (empty where xb <= xa or yb <= ya)."""
    c, r = size
    return max(int(x0), 0), max(int(y0), 0), min(int(x0) + int(cols), c), min(int(y0) + int(rows), r)


class Image:
    """One band of a GDAL raster (a path) or of an in-memory 2-D array (tests, derived images).

    `size` is (cols, rows); `read(x0, y0, cols, rows)` returns (array float32, x0, y0) of the part
    of the window that lies inside the image (possibly empty), with the masked pixels (module
    docstring) set to NaN.

    nodata: the nodata value (default: the band's); saturation: None (saturated pixels are data), a
    value (pixels at or above it are masked), or True: the largest value of the data type (255 for
    Byte, 65535 for UInt16, ...; none for floating-point data) or 2^NBITS - 1 where the raster's
    IMAGE_STRUCTURE metadata gives NBITS (12-bit imagery stored as UInt16). `saturation` holds the value
    (None: not masked)."""

    def __init__(
        self,
        source: "str | os.PathLike | np.ndarray",
        band: int = 1,
        nodata: "float | None" = None,
        saturation: "bool | float | None" = None,
    ):
        self._array = None
        self._dataset = None
        self._mask_band = False  # the band has a GDAL mask of its own (not all-valid, not nodata)
        self.band = int(band)
        self._lock = threading.Lock()  # a GDAL dataset is not thread-safe
        if isinstance(source, np.ndarray):
            if source.ndim != 2 or source.size == 0:
                raise InputError(f"an image array must be 2-D and non-empty, got shape {source.shape}")
            self._array = np.asarray(source, dtype=np.float32)
            self.path = None
            self.nodata = nodata
            self.saturation = _saturation(saturation, source.dtype)
            self.size = (int(source.shape[1]), int(source.shape[0]))
            return
        from osgeo import gdal, gdal_array

        self.path = os.fspath(source)
        try:
            gdal.UseExceptions()
            dataset = gdal.Open(self.path, gdal.GA_ReadOnly)
        except RuntimeError as exc:
            raise InputError(f"cannot open the image {self.path}: {exc}") from None
        if dataset is None:
            raise InputError(f"cannot open the image {self.path}")
        if not 1 <= self.band <= dataset.RasterCount:
            raise InputError(f"the image {self.path} has {dataset.RasterCount} band(s), band {self.band} asked for")
        self._dataset = dataset
        rb = dataset.GetRasterBand(self.band)
        self.nodata = rb.GetNoDataValue() if nodata is None else nodata
        self._mask_band = not rb.GetMaskFlags() & (gdal.GMF_ALL_VALID | gdal.GMF_NODATA)
        bits = rb.GetMetadataItem("NBITS", "IMAGE_STRUCTURE")
        dtype = gdal_array.GDALTypeCodeToNumericTypeCode(rb.DataType)
        self.saturation = _saturation(saturation, np.dtype(dtype or np.float64), int(bits) if bits else None)
        self.size = (int(dataset.RasterXSize), int(dataset.RasterYSize))

    def __repr__(self):
        return f"Image({self.path or 'array'}, {self.size[0]} x {self.size[1]})"

    def __reduce__(self):
        """Pickled as what it was opened from (a worker process reopens the raster by its path; the
        path must be the same there: a shared file system)."""
        return Image, (self.path if self._array is None else self._array, self.band, self.nodata, self.saturation)

    def read(self, x0, y0, cols, rows):
        """Window of `cols` x `rows` pixels whose top-left corner is pixel (x0, y0), clipped to
        the image: returns (float32 array, x0, y0) of the clipped window (shape (0, 0) when the
        window misses the image)."""
        xa, ya, xb, yb = clipped(self.size, x0, y0, cols, rows)
        if xb <= xa or yb <= ya:
            return np.zeros((0, 0), np.float32), xa, ya
        valid = None
        if self._array is not None:
            data = self._array[ya:yb, xa:xb].copy()
        else:
            with self._lock:
                band = self._dataset.GetRasterBand(self.band)
                data = band.ReadAsArray(xa, ya, xb - xa, yb - ya)
                if self._mask_band and data is not None:
                    valid = band.GetMaskBand().ReadAsArray(xa, ya, xb - xa, yb - ya)
            if data is None or (self._mask_band and valid is None):
                raise InputError(f"cannot read the window ({xa}, {ya}, {xb - xa}, {yb - ya}) of {self.path}")
            data = data.astype(np.float32)
        if self.nodata is not None:
            data[data == np.float32(self.nodata)] = np.nan
        if valid is not None:
            data[valid == 0] = np.nan
        if self.saturation is not None:
            data[data >= np.float32(self.saturation)] = np.nan
        return np.ascontiguousarray(data), xa, ya


def _saturation(saturation: "bool | float | None", dtype: np.dtype, bits: "int | None" = None) -> "float | None":
    """Image's saturation value (its docstring) for the argument `saturation` and data type `dtype`."""
    if saturation is None or saturation is False:
        return None
    if saturation is not True:
        return float(saturation)
    if bits:
        return float(2**bits - 1)
    return float(np.iinfo(dtype).max) if np.issubdtype(dtype, np.integer) else None


class Window:
    """The part (x0, y0, cols, rows) of an Image-like `image` (inside it) as an Image of its own:
    positions relative to the window's top-left corner, reads clipped to the window."""

    def __init__(self, image, x0, y0, cols, rows):
        self.image = image
        self.x0, self.y0 = int(x0), int(y0)
        self.size = (int(cols), int(rows))

    def __repr__(self):
        return f"Window({self.image!r}, {self.x0}, {self.y0}, {self.size[0]} x {self.size[1]})"

    def read(self, x0, y0, cols, rows):
        """As Image.read, in window coordinates."""
        xa, ya, xb, yb = clipped(self.size, x0, y0, cols, rows)
        if xb <= xa or yb <= ya:
            return np.zeros((0, 0), np.float32), xa, ya
        data, xr, yr = self.image.read(self.x0 + xa, self.y0 + ya, xb - xa, yb - ya)
        return data, xr - self.x0, yr - self.y0


class Smoothed:
    """An Image seen through a separable Gaussian low-pass of standard deviation (sigma_x,
    sigma_y) px, with the Image interface (`size`, `read`). A window is read with a border of
    4 sigma and filtered, so its values do not depend on where the window was cut; nodata (NaN)
    spreads over the filter's support (cannot match there)."""

    def __init__(self, image, sigma_x, sigma_y):
        self.image = as_image(image)
        self.size = self.image.size
        self.sigma = (float(sigma_y), float(sigma_x))  # array axes (rows, cols)
        self.pad = int(math.ceil(4.0 * max(self.sigma))) + 1

    def __repr__(self):
        return f"Smoothed({self.image!r}, sigma x {self.sigma[1]:.2f} px, y {self.sigma[0]:.2f} px)"

    def read(self, x0, y0, cols, rows):
        """As Image.read, of the low-passed image."""
        from scipy import ndimage

        p = self.pad
        data, xa, ya = self.image.read(int(x0) - p, int(y0) - p, int(cols) + 2 * p, int(rows) + 2 * p)
        if data.size == 0:
            return data, xa, ya
        data = ndimage.gaussian_filter(data, self.sigma, mode="nearest", truncate=4.0)
        xs, ys, xb, yb = clipped(self.size, x0, y0, cols, rows)
        if xb <= xs or yb <= ys:
            return np.zeros((0, 0), np.float32), xs, ys
        return np.ascontiguousarray(data[ys - ya : yb - ya, xs - xa : xb - xa]), xs, ys


def as_image(source, saturation: "bool | float | None" = None):
    """An Image for a path or an array (masking its saturated pixels as Image's `saturation` says), or the
    Image-like `source` itself."""
    return source if isinstance(source, (Image, Smoothed, Window)) else Image(source, saturation=saturation)


def touches_masked(
    image, x: np.ndarray, y: np.ndarray, reach_x: "float | np.ndarray", reach_y: "float | np.ndarray"
) -> np.ndarray:
    """Mask of the points (x, y) whose window holds a masked pixel (NaN) of the Image-like `image`: the
    window of a point is the pixels whose centres lie within reach_x px across and reach_y px down of it
    (numbers, or arrays like x). The parts of a window outside the image do not count (the matchers test
    the image's edge themselves); a point with a NaN coordinate touches nothing. One read of the window
    that holds every point's window: give the points of one tile."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    rx, ry = np.broadcast_to(reach_x, x.shape), np.broadcast_to(reach_y, x.shape)
    out = np.zeros(x.shape, bool)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return out
    x, y, rx, ry = x[ok], y[ok], rx[ok], ry[ok]
    # first and last column and row of each window (pixel j has its centre at j + 0.5)
    j0, j1 = np.ceil(x - rx - 0.5).astype(np.int64), np.floor(x + rx - 0.5).astype(np.int64)
    i0, i1 = np.ceil(y - ry - 0.5).astype(np.int64), np.floor(y + ry - 0.5).astype(np.int64)
    xa, ya = int(j0.min()), int(i0.min())
    data, ox, oy = image.read(xa, ya, int(j1.max()) + 1 - xa, int(i1.max()) + 1 - ya)
    if data.size == 0:
        return out
    rows, cols = data.shape
    counts = np.zeros((rows + 1, cols + 1), np.int64)
    counts[1:, 1:] = np.isnan(data).cumsum(axis=0).cumsum(axis=1)
    a0, a1 = np.clip(j0 - ox, 0, cols), np.clip(j1 + 1 - ox, 0, cols)
    b0, b1 = np.clip(i0 - oy, 0, rows), np.clip(i1 + 1 - oy, 0, rows)
    out[ok] = (counts[b1, a1] - counts[b0, a1] - counts[b1, a0] + counts[b0, a0]) > 0
    return out
