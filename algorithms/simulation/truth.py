"""The true, continuous geometry of one simulated image, and its sampling into a SpotOrientation.

Rays come from the analytic orbit and attitude at the exact line time and from the continuous
look angles, never from sampled ephemeris, so a sensor model that interpolates the sampled
orientation is checked independently. Line time of GDAL row coordinate r:
t = t_c + (r - r_c) T; pixel (col j, row k) is the ray of detector p = j + 0.5 at row k + 0.5."""

import math
from dataclasses import dataclass

import numpy as np

from ..sensors.spot_orientation import Corrections, SpotOrientation
from .instruments import Instrument, LookAngles
from .orbit import Attitude, CircularOrbit, look_residual, newton
from .render import line_matrices

ATTITUDE_RATE = 8.0  # Hz, attitude samples (SPOT 5 corrected attitudes, SPOT 1-4 speeds)
ATTITUDE_MARGIN = 2.0  # s of attitude samples before the first and after the last line
EPHEMERIS_MARGIN_POINTS = 4  # ephemeris samples at least this many each side of the scene


@dataclass
class ImageTruth:
    """Continuous truth of one image (module docstring)."""

    instrument: Instrument
    orbit: CircularOrbit
    attitude: Attitude
    look: LookAngles
    ncols: int
    nrows: int
    centre_time: float  # s since epoch, time of row coordinate centre_row
    centre_row: float
    epoch: np.datetime64

    @property
    def name(self):
        return self.instrument.name

    def row_time(self, row):
        return self.centre_time + (np.asarray(row, dtype=np.float64) - self.centre_row) * self.instrument.line_period

    def line_geometry(self, rows=None):
        """Satellite positions (n, 3) and R32 R21 (n, 9) at row coordinates `rows` (default: the
        centres k + 0.5 of all rows)."""
        rows = np.arange(self.nrows) + 0.5 if rows is None else np.asarray(rows, dtype=np.float64)
        t = self.row_time(rows)
        pos, vel = self.orbit.state(t)
        return np.ascontiguousarray(pos), line_matrices(
            np.ascontiguousarray(pos), np.ascontiguousarray(vel), np.ascontiguousarray(self.attitude.angles(t))
        )

    def look_vectors(self, cols=None):
        """Navigation-frame look vectors u1 (n, 3) of column coordinates `cols` (default: the
        detector centres j + 0.5)."""
        p = np.arange(self.ncols) + 0.5 if cols is None else np.asarray(cols, dtype=np.float64)
        psi_x, psi_y = self.look(p)
        return np.column_stack([-np.tan(psi_y), np.tan(psi_x), -np.ones_like(psi_x)])

    def ground_to_image(self, xyz):
        """Image (col, row) coordinates of ECEF points (n, 3): Newton on (t, p) for
        look angles seen at t == look angles of detector p."""
        xyz = np.atleast_2d(np.asarray(xyz, dtype=np.float64))
        out = np.empty((len(xyz), 2))
        for k, target in enumerate(xyz):

            def residual(v):
                return look_residual(self.orbit, self.attitude, v[0], target, *self.look(v[1]))

            t, p = newton(
                residual,
                np.array([self.centre_time, 0.5 * self.ncols]),
                np.array([1e-4, 1e-3]),
                np.array([1e-9, 1e-7]),
                "image position of a ground point",
            )
            out[k] = p, self.centre_row + (t - self.centre_time) / self.instrument.line_period
        return out[:, 0], out[:, 1]

    def time_span(self):
        """(first, last) acquisition time: top edge of row 0 and bottom edge of the last row."""
        return float(self.row_time(0.0)), float(self.row_time(float(self.nrows)))

    def orientation(self, corrections=None):
        """The orientation a producer would deliver, sampled from the truth: ephemeris every
        `ephemeris_step` s with >= 4 samples beyond each end, attitude at 8 Hz (SPOT 1-4: two raw
        angles and 8 Hz angular speeds), per-detector look angles. With `corrections` (the
        injected errors) the result is the *supplied* orientation: truth minus the correction
        polynomials, so that supplied + corrections = truth."""
        ins = self.instrument
        c = corrections or Corrections()
        first, last = self.time_span()
        step = ins.ephemeris_step
        k = np.arange(
            math.floor(first / step) - EPHEMERIS_MARGIN_POINTS + 1, math.ceil(last / step) + EPHEMERIS_MARGIN_POINTS
        )
        eph_t = k * step
        pos, vel = self.orbit.state(eph_t)
        tau = (eph_t - self.centre_time) / c.time_scale
        pos = pos - _poly(c.position, tau)
        vel = vel - _poly_rate(c.position, tau) / c.time_scale
        dt = 1.0 / ATTITUDE_RATE
        att_t = dt * np.arange(math.floor((first - ATTITUDE_MARGIN) / dt), math.ceil((last + ATTITUDE_MARGIN) / dt) + 1)
        tau = (att_t - self.centre_time) / c.time_scale
        att_ypr = self.attitude.angles(att_t) - _poly(c.attitude, tau)
        speed_t = speed_ypr = None
        if ins.mission < 5:
            speed_t = att_t
            speed_ypr = self.attitude.rates(att_t) - _poly_rate(c.attitude, tau) / c.time_scale
            att_t, att_ypr = att_t[[0, -1]], att_ypr[[0, -1]]
        p = np.arange(self.ncols) + 0.5
        psi_x, psi_y = self.look(p)
        q = (p - 0.5 * self.ncols) / 1000.0
        psi_x = psi_x - _poly(c.look[:1], q)[:, 0]
        psi_y = psi_y - _poly(c.look[1:], q)[:, 0]
        if ins.mission < 5:  # SPOT 1-4 DIMAP: first and last detector, linear between (bit-exact)
            psi_x, psi_y = (np.interp(p, p[[0, -1]], v[[0, -1]]) for v in (psi_x, psi_y))
        return SpotOrientation(
            mission=ins.mission,
            instrument=ins.instrument,
            instrument_index=ins.instrument_index,
            ncols=self.ncols,
            nrows=self.nrows,
            epoch=self.epoch,
            eph_t=eph_t,
            eph_pos=pos,
            eph_vel=vel,
            att_t=att_t,
            att_ypr=att_ypr,
            psi_x=psi_x,
            psi_y=psi_y,
            line_period=ins.line_period,
            centre_time=self.centre_time,
            centre_row=self.centre_row,
            speed_t=speed_t,
            speed_ypr=speed_ypr,
            sensor_code=ins.sensor_code,
            name=f"simulated {ins.name}",
        )


def _poly(coef, tau):
    """sum_j coef[k, j] tau^j as an (n, k) array."""
    return np.polynomial.polynomial.polyval(np.asarray(tau), np.asarray(coef, dtype=np.float64).T).T


def _poly_rate(coef, tau):
    """d/dtau of `_poly`."""
    return _poly(np.polynomial.polynomial.polyder(np.asarray(coef, dtype=np.float64), axis=1), tau)
