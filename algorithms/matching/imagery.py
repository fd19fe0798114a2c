"""Windowed access to one band of a raster, so the matchers' memory is bounded by the tile size,
not the scene size.

Coordinates are GDAL's: a window read at (x0, y0) returns array pixel (i, j) with its centre at
image position (x0 + j + 0.5, y0 + i + 0.5). Nodata pixels come back as NaN, which the matchers
treat as "cannot match here" (a NaN correlation fails every acceptance test)."""
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
    of the window that lies inside the image (possibly empty), with nodata set to NaN."""

    def __init__(self, source, band=1, nodata=None):
        self._array = None
        self._dataset = None
        self.band = int(band)
        self._lock = threading.Lock()   # a GDAL dataset is not thread-safe
        if isinstance(source, np.ndarray):
            if source.ndim != 2 or source.size == 0:
                raise InputError(f"an image array must be 2-D and non-empty, got shape {source.shape}")
            self._array = np.asarray(source, dtype=np.float32)
            self.path = None
            self.nodata = nodata
            self.size = (int(source.shape[1]), int(source.shape[0]))
            return
        from osgeo import gdal
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
        self.size = (int(dataset.RasterXSize), int(dataset.RasterYSize))

    def __repr__(self):
        return f"Image({self.path or 'array'}, {self.size[0]} x {self.size[1]})"

    def __reduce__(self):
        """Pickled as what it was opened from (a worker process reopens the raster by its path; the
        path must be the same there: a shared file system)."""
        return Image, (self.path if self._array is None else self._array, self.band, self.nodata)

    def read(self, x0, y0, cols, rows):
        """Window of `cols` x `rows` pixels whose top-left corner is pixel (x0, y0), clipped to
        the image: returns (float32 array, x0, y0) of the clipped window (shape (0, 0) when the
        window misses the image)."""
        xa, ya, xb, yb = clipped(self.size, x0, y0, cols, rows)
        if xb <= xa or yb <= ya:
            return np.zeros((0, 0), np.float32), xa, ya
        if self._array is not None:
            data = self._array[ya:yb, xa:xb].copy()
        else:
            with self._lock:
                data = self._dataset.GetRasterBand(self.band).ReadAsArray(xa, ya, xb - xa, yb - ya)
            if data is None:
                raise InputError(f"cannot read the window ({xa}, {ya}, {xb - xa}, {yb - ya}) of {self.path}")
            data = data.astype(np.float32)
        if self.nodata is not None:
            data[data == np.float32(self.nodata)] = np.nan
        return np.ascontiguousarray(data), xa, ya


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
        self.sigma = (float(sigma_y), float(sigma_x))      # array axes (rows, cols)
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
        return np.ascontiguousarray(data[ys - ya:yb - ya, xs - xa:xb - xa]), xs, ys


def as_image(source):
    """An Image for a path, an array or an Image."""
    return source if isinstance(source, (Image, Smoothed, Window)) else Image(source)
