"""Rigorous SPOT 1-5 level-1A sensor model (SPOT Satellite Geometry Handbook).

Ground point of image point (col, row): X = P(t) + mu R32(t) R21(t) u1(col), t = t_c + (row - r_c) T,
u1 = (-tan psi_y, tan psi_x, -1) (frames in spot_frames.py, kernels in spot_kernels.py).

- Position/velocity: 8-point Lagrange interpolation of the ephemeris; one window (the 8 samples
  nearest the scene centre) for the whole scene, so the trajectory is one smooth polynomial.
- Attitude: SPOT 5 Corrected_Attitudes (8 Hz) interpolated linearly. SPOT 1-4: with
  `drift=True` (default) the angular speeds (gyros) are integrated (trapezoid, rates held constant
  beyond their samples) and the integration constant is fitted to the Raw_Attitudes angles; with
  `drift=False` the attitude is nominal (yaw = pitch = roll = 0).
  Why drift is on by default: the handbook builds SPOT 1-4 attitude by integrating the speeds, and
  the data are physical: on the SPOT 2 test scene the integral of the speeds between the two
  absolute angle samples equals their difference to 0.3 microrad, and the integrated pitch spans
  14 microrad within the scene, far above the gyro quantisation (a random walk of about
  0.1 microrad); it bends the scene by up to 6.7 m away from any linear drift, which neither the
  nominal attitude nor a corner fit can represent. The producer's corners do not decide: they lie
  on the first and last lines, and CNES computed them with nominal attitude (drift off: all four
  off by the same 2.65 m along track, probably SCENE_CENTER_TIME rounded to the millisecond;
  drift on: 3.7-7.2 m).
- Look angles: per detector, linear between detector centres (extrapolated beyond the end ones).
- No light-time or aberration correction: the producer's SPOT 5 corners are reproduced to 0.05 m
  without them, whereas aberration (v/c = 25 microrad) would move points by about 20 m and the
  light time (2.8 ms, the Earth turning by up to 1.3 m) by about a metre. CNES's in-flight
  calibrated look angles absorb both, so adding them here would be wrong.
- Corrections (orientation.corrections) are applied inside the kernels, read at each call.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import GeometryError, InputError
from ..geodesy import flat_points, geodetic_to_ecef
from . import spot_kernels as k
from .base import Coordinate, SensorModel, shaped_points
from .dimap import read_dimap
from .spot_orientation import SpotOrientation

if TYPE_CHECKING:
    from ..dem import Dem

LAGRANGE_POINTS = 8

#: names of the 32 correction coefficients, in the order of `partials` (degree j of each row)
PARAMETER_NAMES = [
    f"{name}_{j}" for name in ("X", "Y", "Z", "yaw", "pitch", "roll", "psi_x", "psi_y") for j in range(4)
]


def lagrange_window(
    t: np.ndarray, pos: np.ndarray, vel: np.ndarray, t_centre: float, n: int = LAGRANGE_POINTS
) -> np.ndarray:
    """Packed Lagrange window (n, 8) [t, w, X, Y, Z, VX, VY, VZ] of the n samples nearest t_centre;
    w_j = 1 / prod_k!=j (t_j - t_k) (barycentric weights)."""
    idx = np.sort(np.argsort(np.abs(t - t_centre), kind="stable")[:n])
    tw = t[idx]
    w = np.array([1.0 / np.prod(tw[j] - np.delete(tw, j)) for j in range(tw.size)])
    return np.column_stack([tw, w, pos[idx], vel[idx]])


def integrated_attitude(
    angle_t: np.ndarray, angles: np.ndarray, speed_t: np.ndarray, speeds: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """SPOT 1-4 attitude samples from angular speeds: a(t) = a0 + integral of the rates (trapezoid
    over the rate samples, constant rates beyond them), evaluated at the union of the sample times;
    a0 is fitted (mean) to the absolute angle samples."""
    knots = np.union1d(speed_t, angle_t)
    rates = np.column_stack([np.interp(knots, speed_t, speeds[:, i]) for i in range(3)])
    steps = 0.5 * (rates[1:] + rates[:-1]) * np.diff(knots)[:, None]
    integral = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])
    at_angles = np.column_stack([np.interp(angle_t, knots, integral[:, i]) for i in range(3)])
    return knots, integral + np.mean(angles - at_angles, axis=0)


class SpotModel(SensorModel):
    """Rigorous model of one SPOT 1-5 level-1A scene (see the module docstring)."""

    #: convergence of ground_to_image, rows
    #: d_corrections columns of the exterior orientation (position, attitude), before the look angles
    EXTERIOR_COEFFICIENTS = 24
    TOLERANCE = 1e-7
    MAX_ITERATIONS = 30
    #: central-difference step of `partials` in the position (m; velocity: m per time scale)
    POSITION_STEP = 1.0

    def __init__(self, orientation: SpotOrientation, drift: bool = True) -> None:
        orientation.validate()
        self._orientation = orientation
        self.drift = bool(drift)
        o = orientation
        self._eph = lagrange_window(o.eph_t, o.eph_pos, o.eph_vel, o.centre_time)
        if o.mission == 5:
            att_t, att_v = o.att_t, o.att_ypr
        elif self.drift and o.speed_t is not None and o.speed_ypr is not None and len(o.speed_t):
            att_t, att_v = integrated_attitude(o.att_t, o.att_ypr, o.speed_t, o.speed_ypr)
        else:
            att_t, att_v = np.zeros(1), np.zeros((1, 3))
        self._att_t = np.ascontiguousarray(att_t, dtype=np.float64)
        self._att_v = np.ascontiguousarray(att_v, dtype=np.float64)
        self._look = np.ascontiguousarray(np.column_stack([o.psi_x, o.psi_y]), dtype=np.float64)
        self._guess = self._row_guess()

    def _row_guess(self) -> np.ndarray:
        """Starting values of ground_to_image: row as a quadratic polynomial of ECEF, fitted to
        7 x 7 image points at heights -500, 3000, 9000 m (see spot_kernels.guess_row)."""
        cols, rows = self.size
        c, r, h = (
            v.ravel() for v in np.meshgrid(np.linspace(0, cols, 7), np.linspace(0, rows, 7), [-500.0, 3000.0, 9000.0])
        )
        xyz = geodetic_to_ecef(*self.image_to_ground(c, r, h), h)
        ok = np.all(np.isfinite(xyz), axis=1)
        if ok.sum() < 20:  # degenerate geometry: start every search at the scene centre
            return np.concatenate([np.zeros(3), [1e5, self._orientation.centre_row], np.zeros(9)])
        centre = xyz[ok].mean(axis=0)
        u, v, w = ((xyz[ok] - centre) / 1e5).T
        design = np.column_stack([np.ones_like(u), u, v, w, u * u, v * v, w * w, u * v, u * w, v * w])
        coef = np.linalg.lstsq(design, r[ok], rcond=None)[0]
        return np.concatenate([centre, [1e5], coef])

    @classmethod
    def from_dimap(
        cls, path: str | os.PathLike[str], image: str | os.PathLike[str] | None = None, drift: bool = True
    ) -> SpotModel:
        """Model of a METADATA.DIM (or product folder); `image` (optional raster) must match its size."""
        return cls(read_dimap(path, image=image), drift=drift)

    @property
    def orientation(self) -> SpotOrientation:
        return self._orientation

    @property
    def location_sigma(self) -> float:
        """SensorModel.location_sigma: SPOT 5 (DORIS orbits, star tracker attitude) 50 m rms, SPOT Image's
        specification of its level 1A products without control; SPOT 1-4 1000 m, the absolute accuracy of their
        header positions (Heipke et al. 1992, section 4.1.1; adjustment.parameters.LAGRANGE_PRIORS)."""
        return 50.0 if self._orientation.mission == 5 else 1000.0

    @property
    def size(self) -> tuple[int, int]:
        return self._orientation.ncols, self._orientation.nrows

    def _packed(self) -> k.PackedModel:
        """Kernel inputs with the current corrections (read at each call: the adjustment edits them)."""
        o = self._orientation
        c = o.corrections
        prm = np.array([o.centre_time, o.centre_row, o.line_period, c.time_scale, o.ncols / 2.0])
        corr = np.ascontiguousarray(np.vstack([c.position, c.attitude, c.look]), dtype=np.float64)
        if corr.shape != (8, 4) or not np.all(np.isfinite(corr)) or not c.time_scale > 0:
            raise InputError(
                "corrections must be finite (3, 4), (3, 4), (2, 4) coefficient arrays and a positive time scale"
            )
        return k.PackedModel(self._eph, self._att_t, self._att_v, self._look, prm, corr)

    def image_to_ground(self, col: ArrayLike, row: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """(lon, lat) in degrees of image point (col, row) at ellipsoidal height h; NaN if the ray
        misses that height or the line's time lies outside the ephemeris window (no extrapolation)."""
        (c, r, hh), shape, scalar = flat_points(col, row, h)
        lon, lat = np.empty(c.size), np.empty(c.size)
        k.image_to_ground_kernel(self._packed(), c, r, hh, lon, lat)
        return shaped_points((lon, lat), shape, scalar)

    def ground_to_image(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """(col, row) of ground point (lon, lat, h); converged to 1e-7 row, NaN where no solution."""
        (lo, la, hh), shape, scalar = flat_points(lon, lat, h)
        col, row = np.empty(lo.size), np.empty(lo.size)
        k.ground_to_image_kernel(self._packed(), self._guess, lo, la, hh, self.TOLERANCE, self.MAX_ITERATIONS, col, row)
        return shaped_points((col, row), shape, scalar)

    def line_of_sight(self, col: ArrayLike, row: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Satellite ECEF position (..., 3) and unit ECEF look direction (..., 3) of image points."""
        (c, r), shape, _ = flat_points(col, row)
        pos, direction = np.empty((c.size, 3)), np.empty((c.size, 3))
        k.line_of_sight_kernel(self._packed(), c, r, pos, direction)
        return pos.reshape(shape + (3,)), direction.reshape(shape + (3,))

    def ray_points(self, col: np.ndarray, row: np.ndarray, h: float, half: float) -> tuple[np.ndarray, np.ndarray]:
        """As SensorModel.ray_points, on the straight line of sight: the ground point at height h
        -+ `half` metres along the ray (one ground intersection instead of two)."""
        lon, lat = self.image_to_ground_or_nan(col, row, np.full(np.size(col), h))
        mid = geodetic_to_ecef(lon, lat, h)
        direction = self.line_of_sight(col, row)[1]
        return mid - half * direction, mid + half * direction

    def partials(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike, exterior: bool = True) -> dict[str, np.ndarray]:
        """Image coordinates of ground points and their partial derivatives.

        Returns a dict: col, row (n,); d_corrections (n, 2, 32) = d(col, row)/d(coefficient), the
        coefficients ordered as PARAMETER_NAMES (corrections.position, .attitude, .look, rows then
        degree); d_ecef (n, 2, 3) = d(col, row)/d(X, Y, Z) in px/m; d_ground (n, 2, 3) =
        d(col, row)/d(lon, lat, h) in px/degree, px/degree, px/m. `exterior` False: the position
        and attitude coefficients' columns (the first EXTERIOR_COEFFICIENTS) are 0, not computed."""
        (lo, la, hh), _, _ = flat_points(lon, lat, h)
        col, row = (np.asarray(v) for v in self.ground_to_image(lo, la, hh))  # arrays: lo, la, hh are
        d_corr, d_xyz, d_ground = np.empty((lo.size, 2, 32)), np.empty((lo.size, 2, 3)), np.empty((lo.size, 2, 3))
        k.partials_kernel(self._packed(), lo, la, hh, col, row, self.POSITION_STEP, exterior, d_corr, d_xyz, d_ground)
        return {"col": col, "row": row, "d_corrections": d_corr, "d_ecef": d_xyz, "d_ground": d_ground}

    def image_to_dem(
        self, col: ArrayLike, row: ArrayLike, dem: Dem, samples: int = 64, tol: float = 1e-3
    ) -> tuple[Coordinate, Coordinate, Coordinate]:
        """Ground (lon, lat, h) where the ray of (col, row) first meets the DEM surface.

        Same semantics as SensorModel.image_to_dem (scan from the DEM's maximum down to its minimum
        in at least `samples` steps of at most a quarter DEM cell, first crossing, refined to `tol` m),
        in one numba kernel per call.
        Raises GeometryError where a ray never meets the DEM."""
        (c, r), shape, scalar = flat_points(col, row)
        hmin, hmax = dem.height_range
        out = np.empty((c.size, 3))
        k.image_to_dem_kernel(
            self._packed(),
            c,
            r,
            dem.heights,
            np.asarray(dem.geotransform, dtype=np.float64),
            hmin - 1.0,
            hmax + 1.0,
            int(samples),
            float(tol),
            out,
        )
        bad = np.flatnonzero(np.isnan(out[:, 0]))
        if bad.size:
            raise GeometryError(
                f"the line of sight of image point ({c[bad[0]]:.1f}, {r[bad[0]]:.1f}) does not meet the DEM "
                f"({bad.size} of {c.size} points); is the DEM covering the whole image footprint?"
            )
        return shaped_points((out[:, 0], out[:, 1], out[:, 2]), shape, scalar)

    def __repr__(self) -> str:
        o = self._orientation
        return (
            f"SpotModel(SPOT {o.mission} {o.instrument}{o.instrument_index} {o.sensor_code}, "
            f"{o.ncols} x {o.nrows}, drift={self.drift})"
        )


__all__ = ["SpotModel", "PARAMETER_NAMES", "lagrange_window", "integrated_attitude"]
