"""Colours of object points from the block's images, for the LAS colour fields (point format 7: Red, Green, Blue,
16 bits each).

A point takes the pixel of the first image of the block (in block order) that observes it, nearest to its
measured image position (col, row: pixel-is-area, so the pixel is floor(col), floor(row)); for a triplet's dense
points that is the reference image, whose lattice they were matched on. An image of one band gives grey (the
same value in the three fields); of three or more bands, its bands 1, 2 and 3 are red, green and blue (a
multispectral image in another band order shows in false colour, as its bands lie).

Each band is stretched linearly to 0-65535 between mean - 2.5 sigma and mean + 2.5 sigma of its values (clipped
to its minimum and maximum, its nodata left out), from a read of at most STATS_SIDE pixels a side, computed once
per image before the parts run, so that the colours of every part of a cloud agree and a 12-bit image does not
look black in a viewer that takes 16 bits. Nothing is written beside the images (GDAL's GetStatistics would save
an .aux.xml there).

A part reads, per image, block by block of BLOCK pixels a side, the window of the pixels its points fall in there
(memory follows the block, whatever the part's spread). A point whose pixel lies outside an image takes the next
image that observes it; outside all of them, it is black."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from osgeo import gdal

from ..atomic import closing
from ..errors import InputError
from ..tiling import cell_blocks

#: the stretch: mean +- STRETCH_SIGMAS standard deviations of a band
STRETCH_SIGMAS = 2.5
#: pixels a side of the read a band's statistics come from
STATS_SIDE = 1024
#: pixels a side of the blocks a part's points are sampled in (memory follows the block, not the image)
BLOCK = 1024


@dataclass(frozen=True)
class BandStretch:
    """An image's bands for red, green and blue (1-based; one band three times for grey) and each one's (low,
    high) values that map to 0 and 65535."""

    path: str
    bands: tuple[int, int, int]
    low: tuple[float, float, float]
    high: tuple[float, float, float]


def _open(path: str) -> Any:
    gdal.UseExceptions()
    try:
        return gdal.Open(str(path))
    except RuntimeError as exc:
        raise InputError(f"cannot open the image {path} for the points' colours: {exc}") from exc


def band_stretch(path: str) -> BandStretch:
    """The BandStretch of the image raster at `path` (module docstring): each band's statistics from a read of at
    most STATS_SIDE pixels a side (GDAL's GetStatistics would write them beside the image, an input), without its
    nodata."""
    with closing(_open(path)) as ds:
        bands = (1, 2, 3) if ds.RasterCount >= 3 else (1, 1, 1)
        scale = max(ds.RasterXSize, ds.RasterYSize) / STATS_SIDE
        size = (max(1, round(ds.RasterXSize / max(scale, 1))), max(1, round(ds.RasterYSize / max(scale, 1))))
        low, high = [], []
        for b in bands:
            band = ds.GetRasterBand(b)
            values = band.ReadAsArray(buf_xsize=size[0], buf_ysize=size[1]).astype(np.float64).ravel()
            nodata = band.GetNoDataValue()
            values = values[np.isfinite(values) & (values != nodata if nodata is not None else True)]
            if not values.size:
                raise InputError(f"band {b} of the image {path} holds no value to colour the points with")
            mean, std = float(values.mean()), float(values.std())
            low.append(max(float(values.min()), mean - STRETCH_SIGMAS * std))
            high.append(min(float(values.max()), mean + STRETCH_SIGMAS * std))
    return BandStretch(str(path), bands, (low[0], low[1], low[2]), (high[0], high[1], high[2]))


def stretches(paths: dict[int, str]) -> dict[int, BandStretch]:
    """{image id: BandStretch} of the block's images {image id: raster path}."""
    return {image: band_stretch(path) for image, path in paths.items()}


def colours(
    stretch: dict[int, BandStretch],
    points: np.ndarray,
    image_id: np.ndarray,
    point_id: np.ndarray,
    col: np.ndarray,
    row: np.ndarray,
) -> np.ndarray:
    """(n, 3) uint16 red, green, blue of the points `points` (ids) from their observations (image_id, point_id,
    col, row arrays): each from the first image in `stretch`'s order that observes it (module docstring)."""
    out = np.zeros((len(points), 3), np.uint16)
    if not len(points):
        return out
    left = np.ones(len(points), bool)
    col, row = np.asarray(col, float), np.asarray(row, float)
    for image, s in stretch.items():
        if not left.any():
            break
        obs = np.flatnonzero(image_id == image)
        pos = np.searchsorted(points, point_id[obs]).clip(max=len(points) - 1)
        hit = (points[pos] == point_id[obs]) & left[pos]
        obs, pos = obs[hit], pos[hit]
        pos, first = np.unique(pos, return_index=True)  # one observation per point in this image
        obs = obs[first]
        if not len(obs):
            continue
        values, inside = _sample(s, np.floor(col[obs]).astype(np.int64), np.floor(row[obs]).astype(np.int64))
        out[pos[inside]] = values[inside]
        left[pos[inside]] = False  # a point outside this image takes the next one that observes it
    return out


def _sample(s: BandStretch, c: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((n, 3) uint16 stretched pixels (c, r) of the image of `s`, whether each lies on the image), read block by
    block of BLOCK x BLOCK pixels (tiling.cell_blocks) in the band's own type."""
    out = np.zeros((len(c), 3), np.uint16)
    with closing(_open(s.path)) as ds:
        shape = (ds.RasterYSize, ds.RasterXSize)
        inside = (c >= 0) & (r >= 0) & (c < shape[1]) & (r < shape[0])
        for index in cell_blocks(c + 0.5, r + 0.5, shape, BLOCK):
            index = index[inside[index]]
            if not index.size:
                continue
            cb, rb = c[index], r[index]
            c0, r0 = int(cb.min()), int(rb.min())
            width, height = int(cb.max()) - c0 + 1, int(rb.max()) - r0 + 1
            for k, (b, lo, hi) in enumerate(zip(s.bands, s.low, s.high)):
                window = ds.GetRasterBand(b).ReadAsArray(c0, r0, width, height)
                values = window[rb - r0, cb - c0].astype(np.float64)
                scaled = (values - lo) / (hi - lo) if hi > lo else np.zeros_like(values)
                out[index, k] = np.rint(np.clip(scaled, 0.0, 1.0) * 65535.0).astype(np.uint16)
    return out, inside
