"""The sensor-model interface every model implements.

Image coordinates are (col, row) in GDAL's convention: (0, 0) is the top-left corner of the first
pixel. Ground coordinates are WGS 84 longitude/latitude in degrees and ellipsoidal height in
metres.

Failures: a point outside a model's domain (a line beyond the ephemeris, a ground point behind the
horizon) comes back as NaN, so a batch keeps its other points; an iteration that fails inside the
domain raises GeometryError. Callers that need every point (footprints, DEM rays) raise on NaN."""

from __future__ import annotations

from typing import TYPE_CHECKING, overload

import numpy as np
from numpy.typing import ArrayLike

from ..errors import GeometryError
from ..geodesy import flat_points, geodetic_to_ecef

if TYPE_CHECKING:
    from ..dem import Dem
    from ..dem_store import StoredDem

#: one coordinate of the points a model returns: a float where every input was a scalar, else an array of the
#: inputs' broadcast shape (shaped_points)
Coordinate = float | np.ndarray


@overload
def shaped_points(
    values: tuple[np.ndarray, np.ndarray], shape: tuple[int, ...], scalar: bool
) -> tuple[Coordinate, Coordinate]: ...


@overload
def shaped_points(
    values: tuple[np.ndarray, np.ndarray, np.ndarray], shape: tuple[int, ...], scalar: bool
) -> tuple[Coordinate, Coordinate, Coordinate]: ...


def shaped_points(values: tuple[np.ndarray, ...], shape: tuple[int, ...], scalar: bool) -> tuple[Coordinate, ...]:
    """Kernel outputs back to the callers' shape: floats for scalar input, arrays otherwise."""
    return tuple(float(v[0]) if scalar else v.reshape(shape) for v in values)


class SensorModel:
    """Abstract base: subclasses implement `size`, `image_to_ground` and `ground_to_image`."""

    if TYPE_CHECKING:  # read-only for callers: a model defines them as attributes or as properties

        @property
        def size(self) -> tuple[int, int]:
            """(cols, rows) of the image the model describes."""

        @property
        def location_sigma(self) -> float | None:
            """A priori location accuracy of the orientation as supplied, without control points: the standard
            deviation (m) of a ground position along each horizontal axis; None where unknown."""

    else:  # the defaults: no image, accuracy unknown
        size = (0, 0)
        location_sigma = None

    def image_to_ground(self, col: ArrayLike, row: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """Ground (lon, lat) of image point (col, row) at ellipsoidal height h."""
        raise NotImplementedError

    def ground_to_image(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """Image (col, row) of ground point (lon, lat, h)."""
        raise NotImplementedError

    def image_to_ground_or_nan(self, col: ArrayLike, row: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """image_to_ground with NaN, not an error, where a point has no ground point (for batch
        work such as intersection starting values). Models whose image_to_ground already returns
        NaN there use this default."""
        return self.image_to_ground(col, row, h)

    def ray_points(self, col: np.ndarray, row: np.ndarray, h: float, half: float) -> tuple[np.ndarray, np.ndarray]:
        """Two ECEF points (n, 3) on the line of sight of each image point (arrays col, row), about
        its ground point at height h, NaN where it has none: here its ground points at heights
        h -+ half (image_to_ground_or_nan). Models with straight rays may do it in one pass."""
        ends = []
        for height in (h - half, h + half):
            lon, lat = self.image_to_ground_or_nan(col, row, np.full(col.size, height))
            ends.append(geodetic_to_ecef(lon, lat, height))
        return ends[0], ends[1]

    def image_to_dem(
        self, col: ArrayLike, row: ArrayLike, dem: Dem, samples: int = 64, tol: float = 1e-3
    ) -> tuple[Coordinate, Coordinate, Coordinate]:
        """Ground (lon, lat, h) where the ray of (col, row) first meets the DEM surface.

        Bracket and refine along the line of sight: heights from the DEM's maximum down to its
        minimum are sampled (at least `samples` steps, and at most a quarter of a DEM cell apart
        horizontally, so steep terrain, needles and occlusions are bracketed by the first sign
        change of h - dem(lon, lat)), then the bracket is refined by regula falsi with bisection
        safeguards to `tol` metres. Raises GeometryError where a ray never meets the DEM (outside
        its extent)."""
        (c, r), shape, _ = flat_points(col, row)
        hmin, hmax = dem.height_range
        hmin, hmax = hmin - 1.0, hmax + 1.0
        n = c.size
        top, bottom = self.image_to_ground(c, r, np.full(n, hmax)), self.image_to_ground(c, r, np.full(n, hmin))
        shift = np.subtract(np.array(top), np.array(bottom))
        shift[0] = (shift[0] + 180.0) % 360.0 - 180.0  # across the antimeridian
        cells = np.abs(shift) / np.abs([[dem.geotransform[1]], [dem.geotransform[5]]])
        cells = np.nanmax(cells) if n and np.isfinite(cells).any() else 0.0
        hs = np.linspace(hmax, hmin, max(int(samples), int(np.ceil(4.0 * cells))) + 1)
        hi = np.full(n, np.nan)
        lo = np.full(n, np.nan)
        fhi = np.full(n, np.nan)
        flo = np.full(n, np.nan)
        prev_h = None
        prev_f = None
        found = np.zeros(n, bool)
        for h in hs:
            lon, lat = self.image_to_ground(c, r, np.full(n, h))
            f = h - dem.height(lon, lat)
            if prev_f is not None:
                new = ~found & (prev_f >= 0) & (f <= 0)
                hi[new], fhi[new], lo[new], flo[new] = prev_h, prev_f[new], h, f[new]
                found |= new
            prev_h, prev_f = h, f
        if not found.all():
            bad = np.flatnonzero(~found)[0]
            raise GeometryError(
                f"the line of sight of image point ({c[bad]:.1f}, {r[bad]:.1f}) does not meet the DEM; "
                "is the DEM covering the whole image footprint?"
            )
        for _ in range(60):
            denom = fhi - flo
            h = np.where(denom != 0, hi - fhi * (hi - lo) / np.where(denom != 0, denom, 1.0), 0.5 * (hi + lo))
            h = np.where((h <= lo) | (h >= hi), 0.5 * (hi + lo), h)
            lon, lat = self.image_to_ground(c, r, h)
            f = h - dem.height(lon, lat)
            f = np.where(np.isnan(f), -1.0, f)
            upper = f > 0
            hi = np.where(upper, h, hi)
            fhi = np.where(upper, f, fhi)
            lo = np.where(upper, lo, h)
            flo = np.where(upper, flo, f)
            if np.all(np.abs(f) < tol) or np.all(hi - lo < tol):
                break
        return np.reshape(lon, shape), np.reshape(lat, shape), h.reshape(shape)

    def footprint(self, h: float = 0.0, dem: StoredDem | None = None, per_side: int = 16) -> np.ndarray:
        """Closed ring (N, 2) of (lon, lat) along the image border, at height h or on the DEM `dem`
        (dem_store.StoredDem: its `ground` points of the border's rays)."""
        cols, rows = self.size
        t = np.linspace(0.0, 1.0, per_side + 1)[:-1]
        c = np.concatenate([t * cols, np.full(per_side, cols), (1 - t) * cols, np.zeros(per_side)])
        r = np.concatenate([np.zeros(per_side), t * rows, np.full(per_side, rows), (1 - t) * rows])
        if dem is None:
            lon, lat = self.image_to_ground(c, r, np.full(c.size, float(h)))
        else:
            lon, lat, _ = dem.ground(self, c, r)
        ring = np.column_stack([lon, lat])
        if not np.all(np.isfinite(ring)):
            raise GeometryError(
                f"the image border has no ground position at {np.isnan(ring[:, 0]).sum()} of "
                f"{len(ring)} points: is the orientation complete for the whole image?"
            )
        return np.vstack([ring, ring[:1]])
