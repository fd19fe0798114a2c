"""Instruments and acquisition configurations.

- 'spot5_triplet': one SPOT 5 pass, along-track stereo: HRS1 looking forward (psi_x = +20 deg)
  and HRS2 backward (-20 deg), 10 m across x 5 m along (B/H about 0.8), plus the nadir
  panchromatic image of instrument HRG1 ('HRG') at 5 m; the three see the scene centre about 45 s
  apart.
- 'spot14_pair': SPOT 2 HRV panchromatic, across-track stereo from two passes on two dates
  (3 days apart), mirror viewing angles (psi_y of the centre detector) of opposite sign,
  10 m, 8 bit; +-12 deg gives B/H about 0.5.

Look angles per detector p (column coordinate of its centre, p_c the array centre):
psi_x(p) = psi_x0 + dx(p), psi_y(p) = psi_y0 + ifov (p - p_c) + dy(p), where dx, dy are the
non-linear residuals of a real look-angle table (see `table_residuals`) or, by default, a gentle
array curvature for SPOT 5 (the SPOT 1-4 DIMAP format keeps only the first and last detector,
so those arrays stay linear)."""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

NOMINAL_ALTITUDE = 830e3  # m, for the detector angular size ifov = gsd cos(psi_x) / altitude


@dataclass(frozen=True)
class Instrument:
    """One image's instrument: DIMAP identity, viewing geometry and sampling."""

    name: str  # image folder name
    mission: int
    instrument: str
    instrument_index: int
    sensor_code: str
    psi_x: float  # along-track look angle of the array, rad
    gsd: float  # across-track ground sampling at the array centre, m
    line_period: float  # s
    pass_index: int  # which pass (orbit/date) of the configuration
    reference: bool  # the pass's orbit is solved for this image's centre detector
    ephemeris_step: float  # s between ephemeris samples
    detector_lines: float = 1.0  # along-track size of a detector's footprint, in lines (HRS: 10 m
    # detectors sampled every 5 m along track, i.e. 2 lines)

    @property
    def ifov(self):
        """Angular size of a detector, rad."""
        return self.gsd * math.cos(self.psi_x) / NOMINAL_ALTITUDE


CONFIGURATIONS = ("spot5_triplet", "spot14_pair")
DEFAULT_DATES = {"spot5_triplet": ("2005-05-17",), "spot14_pair": ("1999-07-10", "1999-07-13")}
DEFAULT_ROLL_DEG = {"spot5_triplet": (0.0,), "spot14_pair": (12.0, -12.0)}


def instruments(configuration):
    """The images of `configuration` (see the module docstring)."""
    if configuration == "spot5_triplet":
        twenty = math.radians(20.0)
        return [
            Instrument("HRG", 5, "HRG", 1, "A", 0.0, 5.0, 7.52e-4, 0, True, 30.0),
            Instrument("HRS1", 5, "HRS", 1, "P", twenty, 10.0, 7.52e-4, 0, False, 30.0, 2.0),
            Instrument("HRS2", 5, "HRS", 2, "P", -twenty, 10.0, 7.52e-4, 0, False, 30.0, 2.0),
        ]
    if configuration == "spot14_pair":
        return [
            Instrument("HRV1_A", 2, "HRV", 1, "P", 0.0, 10.0, 1.504e-3, 0, True, 60.0),
            Instrument("HRV2_B", 2, "HRV", 2, "P", 0.0, 10.0, 1.504e-3, 1, True, 60.0),
        ]
    raise InputError(f"unknown configuration {configuration!r}; choose one of {', '.join(CONFIGURATIONS)}")


def table_residuals(psi_x, psi_y):
    """Shape of a real look-angle table as functions of the normalised array position
    s in [0, 1]: (s_samples, dx, dy_pixels), dx = psi_x - mean(psi_x) (rad, tilt and curvature of
    the array), dy_pixels = residual of psi_y from its straight line, in detectors."""
    psi_x = np.asarray(psi_x, dtype=np.float64)
    psi_y = np.asarray(psi_y, dtype=np.float64)
    n = psi_y.size
    p = np.arange(n) + 0.5
    line = np.polyfit(p, psi_y, 1)
    s = p / n
    return s, psi_x - psi_x.mean(), (psi_y - np.polyval(line, p)) / abs(line[0])


@dataclass(frozen=True)
class LookAngles:
    """Continuous look angles of an image's detectors (module docstring formula)."""

    psi_x0: float
    psi_y0: float
    ifov: float  # signed: dpsi_y / dp
    ncols: int
    table: tuple = None  # (s, dx, dy_pixels) from `table_residuals`, or None
    curvature: float = 0.0  # rad at the array ends, default smile of psi_x

    def __call__(self, p):
        """(psi_x, psi_y) at column coordinates p (detector j has p = j + 0.5)."""
        p = np.asarray(p, dtype=np.float64)
        q = (p - 0.5 * self.ncols) / (0.5 * self.ncols)
        dx = self.curvature * q * q
        dy = np.zeros_like(p)
        if self.table is not None:
            s, tx, ty = self.table
            dx = dx + np.interp(p / self.ncols, s, tx)
            dy = np.interp(p / self.ncols, s, ty)
        return self.psi_x0 + dx, self.psi_y0 + self.ifov * (p - 0.5 * self.ncols + dy)

    def with_centre(self, psi_y0):
        return LookAngles(self.psi_x0, psi_y0, self.ifov, self.ncols, self.table, self.curvature)
