"""Colours of object points from the block's images, for the LAS colour fields (point format 7: Red, Green, Blue,
16 bits each).

A point takes the pixel of the first image of the block (in block order) that observes it, nearest to its
measured image position (col, row: pixel-is-area, so the pixel is floor(col), floor(row)); for a triplet's dense
points that is the reference image, whose lattice they were matched on. An image of one band gives grey (the
same value in the three fields); of three or more bands, its bands 1, 2 and 3 are red, green and blue (a
multispectral image in another band order shows in false colour, as its bands lie).

Each band is stretched linearly to 0-65535 between mean - 2.5 sigma and mean + 2.5 sigma of its values (clipped
to its minimum and maximum; GDAL's approximate statistics, from an overview where the image has one), computed
once per image before the parts run, so that the colours of every part of a cloud agree and a 12-bit image does
not look black in a viewer that takes 16 bits.

A part reads, per image, the window of the pixels its points fall in (memory follows the part). A point whose
pixel lies outside its image (a measurement at the border) is black."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from osgeo import gdal

from ..atomic import closing
from ..errors import InputError

#: the stretch: mean +- STRETCH_SIGMAS standard deviations of a band
STRETCH_SIGMAS = 2.5


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
    """The BandStretch of the image raster at `path` (module docstring)."""
    with closing(_open(path)) as ds:
        bands = (1, 2, 3) if ds.RasterCount >= 3 else (1, 1, 1)
        low, high = [], []
        for b in bands:
            minimum, maximum, mean, std = ds.GetRasterBand(b).GetStatistics(True, True)
            low.append(max(minimum, mean - STRETCH_SIGMAS * std))
            high.append(min(maximum, mean + STRETCH_SIGMAS * std))
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
        out[pos] = _sample(s, np.floor(col[obs]).astype(np.int64), np.floor(row[obs]).astype(np.int64))
        left[pos] = False
    return out


def _sample(s: BandStretch, c: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 3) uint16 of the stretched pixels (c, r) of the image of `s`; black outside it."""
    out = np.zeros((len(c), 3), np.uint16)
    with closing(_open(s.path)) as ds:
        inside = (c >= 0) & (r >= 0) & (c < ds.RasterXSize) & (r < ds.RasterYSize)
        if not inside.any():
            return out
        c0, r0 = int(c[inside].min()), int(r[inside].min())
        c1, r1 = int(c[inside].max()) + 1, int(r[inside].max()) + 1
        cache: dict[int, np.ndarray] = {}
        for k, (b, lo, hi) in enumerate(zip(s.bands, s.low, s.high)):
            if b not in cache:
                cache[b] = ds.GetRasterBand(b).ReadAsArray(c0, r0, c1 - c0, r1 - r0).astype(np.float64)
            values = cache[b][r[inside] - r0, c[inside] - c0]
            scaled = (values - lo) / (hi - lo) if hi > lo else np.zeros_like(values)
            out[inside, k] = np.rint(np.clip(scaled, 0.0, 1.0) * 65535.0).astype(np.uint16)
    return out
