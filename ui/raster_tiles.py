"""Tiled, cached reading of a raster for display (no Qt): the overview level for a zoom, 256 x 256 tiles
read with windowed ReadAsArray, an LRU tile cache bounded in bytes, a 2-98 % contrast stretch.

An image is never read whole. Levels are the full resolution, the raster's GDAL overviews, then (down to
256 px) "virtual" levels read from the coarsest real level with buf_xsize/buf_ysize decimation (GDAL's
nearest-neighbour downsampling). A raster without overviews therefore still shows zoomed out at a cost
bounded by the screen, but a first zoomed-out view (and the automatic stretch) reads every block of the
image once; build_overviews() writes an external .ovr that makes those reads cheap (the user's choice).

Coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel, its centre (0.5, 0.5)."""

import collections
import math
import os
from typing import NamedTuple

import numpy as np

from ..algorithms import progress
from ..algorithms.atomic import atomic_path, closing
from ..algorithms.errors import CancelledError, InputError
from ..algorithms.surface.geotiff import overview_levels

TILE = 256
#: default byte bound of the tile cache
CACHE_BYTES = 256 * 2**20
#: GDAL's own block cache is emptied of this raster's blocks when GDAL holds more than this
GDAL_CACHE_BYTES = 32 * 2**20
#: the level of the automatic stretch is the coarsest one at least this large (or the full resolution)
STRETCH_SIZE = 1024


class Level(NamedTuple):
    """One resolution: `cols` x `rows` pixels, each `scale_x` x `scale_y` full-resolution pixels; read from
    `source` (0: full resolution, k: GDAL overview k - 1) decimated by `decimation` (1: a real level)."""

    cols: int
    rows: int
    scale_x: float
    scale_y: float
    source: int
    decimation: int


class ByteLru:
    """Least-recently-used mapping bounded by the sum of its values' sizes in bytes (`nbytes`)."""

    def __init__(self, max_bytes):
        self.max_bytes = int(max_bytes)
        self.nbytes = 0
        self._items = collections.OrderedDict()

    def __len__(self):
        return len(self._items)

    def __contains__(self, key):
        return key in self._items

    def keys(self):
        """Keys from the least to the most recently used."""
        return list(self._items)

    def get(self, key):
        """The value for `key` (now the most recent) or None."""
        if key not in self._items:
            return None
        self._items.move_to_end(key)
        return self._items[key][0]

    def put(self, key, value, nbytes):
        """Store `value` of `nbytes` bytes, dropping the least recent values beyond the bound (the newest
        value is kept even when it alone is larger)."""
        if key in self._items:
            self.nbytes -= self._items.pop(key)[1]
        self._items[key] = (value, int(nbytes))
        self.nbytes += int(nbytes)
        while self.nbytes > self.max_bytes and len(self._items) > 1:
            self.nbytes -= self._items.popitem(last=False)[1][1]

    def clear(self):
        self._items.clear()
        self.nbytes = 0


class TileReader:
    """256 x 256 tiles of a raster at every level: band 1 as grey, or bands 1-3 as RGB (3 or more bands).

    tile(level, tx, ty) returns the tile's values in the raster's data type, (h, w) grey or (h, w, 3) RGB,
    from the cache or read synchronously; the cache holds at most `cache_bytes` bytes of tiles."""

    def __init__(self, path, cache_bytes=CACHE_BYTES, gdal_cache_bytes=GDAL_CACHE_BYTES):
        from osgeo import gdal

        gdal.UseExceptions()
        self.path = os.fspath(path)
        try:
            dataset = gdal.Open(self.path, gdal.GA_ReadOnly)
        except RuntimeError as exc:
            raise InputError(f"cannot open the image {self.path}: {exc}") from None
        if dataset is None or dataset.RasterCount == 0:
            raise InputError(f"{self.path} is not a raster GDAL can read")
        count = 3 if dataset.RasterCount >= 3 else 1
        first = dataset.GetRasterBand(1)
        if gdal.DataTypeIsComplex(first.DataType):
            raise InputError(f"{self.path} has complex pixels; convert it to a real-valued image to view it")
        self._dataset = dataset
        self.size = (int(dataset.RasterXSize), int(dataset.RasterYSize))
        self.nodata = first.GetNoDataValue()
        self.cache = ByteLru(cache_bytes)
        self.gdal_cache_bytes = int(gdal_cache_bytes)
        full = [dataset.GetRasterBand(k + 1) for k in range(count)]
        self._sources = [full]
        cols, rows = self.size
        for k in range(first.GetOverviewCount()):
            overviews = [band.GetOverview(k) for band in full]
            ov = overviews[0]
            if ov is not None and ov.XSize < cols and all(o is not None for o in overviews):
                self._sources.append(overviews)
                cols = ov.XSize
        self.levels = self._make_levels()

    @property
    def bands(self):
        """Number of displayed bands: 1 (grey) or 3 (RGB)."""
        return len(self._sources[0])

    def close(self):
        """Release the GDAL dataset and the cached tiles (the reader cannot read afterwards)."""
        self.cache.clear()
        self._sources = []
        self._dataset = None

    def _make_levels(self):
        width, height = self.size
        levels = [
            Level(s[0].XSize, s[0].YSize, width / s[0].XSize, height / s[0].YSize, k, 1)
            for k, s in enumerate(self._sources)
        ]
        last = levels[-1]
        d = 2
        while max(last.cols, last.rows) / (d // 2) > TILE:
            cols, rows = math.ceil(last.cols / d), math.ceil(last.rows / d)
            levels.append(Level(cols, rows, width / cols, height / rows, last.source, d))
            d *= 2
        return levels

    def level_for(self, zoom, aspect=1.0):
        """Index of the coarsest level whose pixels are still at most one screen pixel wide and high when a
        full-resolution column is `zoom` screen pixels wide and a row `zoom * aspect` high."""
        best = 0
        for k, level in enumerate(self.levels):
            if level.scale_x * zoom <= 1.0 + 1e-9 and level.scale_y * zoom * aspect <= 1.0 + 1e-9:
                best = k
        return best

    def tile_range(self, level, col0, row0, col1, row1):
        """(tx0, ty0, tx1, ty1), tiles tx0 <= tx < tx1, ty0 <= ty < ty1 of `level` that cover the
        full-resolution image rectangle [col0, col1) x [row0, row1) (clipped to the image)."""
        lv = self.levels[level]

        def span(a, b, scale, n):
            lo = min(max(int(math.floor(a / scale)) // TILE, 0), (n - 1) // TILE + 1)
            hi = min(max(int(math.ceil(b / scale)) + TILE - 1, 0) // TILE, (n - 1) // TILE + 1)
            return lo, max(hi, lo)

        tx0, tx1 = span(col0, col1, lv.scale_x, lv.cols)
        ty0, ty1 = span(row0, row1, lv.scale_y, lv.rows)
        return tx0, ty0, tx1, ty1

    def tile_bounds(self, level, tx, ty):
        """Full-resolution image rectangle (col0, row0, col1, row1) covered by tile (tx, ty) of `level`."""
        lv = self.levels[level]
        c0, r0 = tx * TILE, ty * TILE
        c1, r1 = min(c0 + TILE, lv.cols), min(r0 + TILE, lv.rows)
        return c0 * lv.scale_x, r0 * lv.scale_y, c1 * lv.scale_x, r1 * lv.scale_y

    def tile(self, level, tx, ty):
        """Tile (tx, ty) of `level`: the cached array, or read now and cached."""
        key = (level, tx, ty)
        data = self.cache.get(key)
        if data is None:
            data = self._read(self.levels[level], tx, ty)
            self.cache.put(key, data, data.nbytes)
        return data

    def _read(self, lv, tx, ty):
        c0, r0 = tx * TILE, ty * TILE
        w, h = min(TILE, lv.cols - c0), min(TILE, lv.rows - r0)
        if w <= 0 or h <= 0 or tx < 0 or ty < 0:
            raise InputError(f"tile ({tx}, {ty}) is outside the {lv.cols} x {lv.rows} level of {self.path}")
        bands = self._sources[lv.source]
        d = lv.decimation
        x0, y0 = c0 * d, r0 * d
        xs, ys = min(w * d, bands[0].XSize - x0), min(h * d, bands[0].YSize - y0)
        planes = [self._read_window(band, x0, y0, xs, ys, w, h, d) for band in bands]
        return planes[0] if len(planes) == 1 else np.ascontiguousarray(np.stack(planes, axis=-1))

    def _read_window(self, band, x0, y0, xs, ys, w, h, d):
        """band.ReadAsArray of the xs x ys source window at (x0, y0) decimated by d to w x h. Read in chunks of
        about one tile of source rows, output row i from source rows y0 + i d ... (so that GDAL samples a
        regular grid, the last chunk squeezed to the window's end); GDAL's block cache is emptied of this
        raster's blocks whenever it holds more than gdal_cache_bytes in all."""
        from osgeo import gdal

        step = max(1, TILE // d)
        parts = []
        for i0 in range(0, h, step):
            i1 = min(i0 + step, h)
            ya, yb = y0 + i0 * d, y0 + min(i1 * d, ys)
            data = band.ReadAsArray(x0, ya, xs, yb - ya, buf_xsize=w, buf_ysize=i1 - i0)
            if data is None:
                raise InputError(f"cannot read the window ({x0}, {ya}, {xs}, {yb - ya}) of {self.path}")
            parts.append(data)
            if gdal.GetCacheUsed() > self.gdal_cache_bytes:
                for source in self._sources:
                    for b in source:
                        b.FlushCache()
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def stretch_level(self):
        """Index of the level the automatic stretch reads: the coarsest at least STRETCH_SIZE px on its
        larger side, or the full resolution."""
        best = 0
        for k, lv in enumerate(self.levels):
            if max(lv.cols, lv.rows) >= STRETCH_SIZE:
                best = k
        return best

    def percentiles(self, low=2.0, high=98.0):
        """(low values, high values), one per displayed band, at the `low` and `high` percentiles of the
        valid pixels (nodata and NaN left out) of stretch_level(), read through the tile cache."""
        k = self.stretch_level()
        lv = self.levels[k]
        tiles = [
            self.tile(k, tx, ty).reshape(-1, self.bands)
            for ty in range((lv.rows - 1) // TILE + 1)
            for tx in range((lv.cols - 1) // TILE + 1)
        ]
        values = np.concatenate(tiles)
        lows, highs = [], []
        for b in range(self.bands):
            v = values[:, b]
            valid = np.isfinite(v) if v.dtype.kind == "f" else np.ones(v.shape, bool)
            if self.nodata is not None:
                valid &= v != self.nodata
            v = v[valid]
            lo, hi = np.percentile(v, [low, high]) if v.size else (0.0, 1.0)
            lows.append(float(lo))
            highs.append(float(hi) if hi > lo else float(lo) + 1.0)
        return np.array(lows), np.array(highs)


class Stretch:
    """Linear contrast stretch to 8 bits: value v -> clip(floor((v - low) / (high - low) * 255 + 0.5), 0,
    255), per band (`low`, `high` scalars or one per band); nodata and NaN -> 0. Integer images of up to
    16 bits go through a lookup table."""

    def __init__(self, low, high, nodata=None):
        self.low = np.atleast_1d(np.asarray(low, dtype=np.float64))
        self.high = np.atleast_1d(np.asarray(high, dtype=np.float64))
        if self.low.shape != self.high.shape or np.any(~(self.high > self.low)):
            raise InputError(f"a contrast stretch needs high > low, got low {low}, high {high}")
        self.nodata = nodata
        self._luts = {}

    def _scale(self, values, band):
        k = band if self.low.size > 1 else 0
        lo, hi = self.low[k], self.high[k]
        out = np.floor((values - lo) * (255.0 / (hi - lo)) + 0.5)
        return np.clip(np.nan_to_num(out, nan=0.0), 0, 255).astype(np.uint8)

    def _lut(self, dtype, band):
        key = (dtype.str, band if self.low.size > 1 else 0)
        if key not in self._luts:
            info = np.iinfo(dtype)
            values = np.arange(info.min, info.max + 1, dtype=np.float64)
            lut = self._scale(values, band)
            if self.nodata is not None and info.min <= self.nodata <= info.max and float(self.nodata).is_integer():
                lut[int(self.nodata) - info.min] = 0
            self._luts[key] = (lut, info.min)
        return self._luts[key]

    def apply(self, data):
        """uint8 array of the shape of `data` ((h, w) or (h, w, bands))."""
        planes = [data] if data.ndim == 2 else [data[..., b] for b in range(data.shape[-1])]
        out = []
        for b, plane in enumerate(planes):
            if plane.dtype.kind in "ui" and plane.dtype.itemsize <= 2:
                lut, offset = self._lut(plane.dtype, b)
                out.append(lut[plane.astype(np.int32) - offset] if offset else lut[plane])
            else:
                scaled = self._scale(plane.astype(np.float64), b)
                if self.nodata is not None:
                    scaled[plane == self.nodata] = 0
                out.append(scaled)
        return out[0] if len(out) == 1 else np.ascontiguousarray(np.stack(out, axis=-1))


def build_overviews(path, feedback=None, factors=None, resampling="AVERAGE"):
    """Write the external overviews `path`.ovr (DEFLATE; factors 2, 4, ... down to 256 px by default) of a
    raster, atomically: they are built for a temporary VRT of the raster beside it, then renamed. Returns
    the .ovr path. GDAL uses the file the next time the raster is opened."""
    from osgeo import gdal

    gdal.UseExceptions()
    path = os.fspath(path)
    try:
        source = gdal.Open(path, gdal.GA_ReadOnly)
    except RuntimeError as exc:
        raise InputError(f"cannot open the image {path}: {exc}") from None
    factors = list(factors or overview_levels((source.RasterYSize, source.RasterXSize)))
    if not factors:
        raise InputError(f"{path} is {source.RasterXSize} x {source.RasterYSize} px: too small for overviews")
    target = path + ".ovr"

    def callback(complete, message, data):
        if feedback is None:
            return 1
        feedback.setProgress(100.0 * complete)
        return 0 if feedback.isCanceled() else 1

    with atomic_path(target) as tmp:
        vrt = tmp[: -len(".ovr")]
        try:
            gdal.Translate(vrt, source, format="VRT")
            with closing(gdal.Open(vrt, gdal.GA_ReadOnly)) as ds:
                try:
                    ds.BuildOverviews(resampling, factors, callback, options=["COMPRESS_OVERVIEW=DEFLATE"])
                except RuntimeError:
                    if feedback is not None and feedback.isCanceled():
                        raise CancelledError("cancelled by the user: no overviews written") from None
                    raise
        finally:
            if os.path.exists(vrt):
                os.unlink(vrt)
    progress.step(feedback, 100)
    return target
