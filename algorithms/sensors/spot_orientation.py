"""The supplied orientation of one SPOT level-1A scene, in the engine's conventions.

This is the contract between the DIMAP reader and writer (`dimap.py`, `dimap_writer.py`), the rigorous model
(`spot.py`) and the simulator: times are seconds since `epoch` (UTC), angles radians, positions
ECEF metres, pixel coordinates in GDAL's convention. The DIMAP 1-based pixel-centre convention is
converted at the reader: DIMAP line L (1-based, centre) is GDAL row L - 0.5, detector D (1-based)
looks through column centre D - 0.5.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np
from numpy.typing import ArrayLike

from ..errors import MetadataError

#: largest NCOLS or NROWS accepted (SPOT 5 THR scenes have 24000)
MAX_SIZE = 100000
#: instruments each SPOT mission carries (MISSION_INDEX -> INSTRUMENT)
INSTRUMENTS = {1: ("HRV",), 2: ("HRV",), 3: ("HRV",), 4: ("HIR", "HRVIR"), 5: ("HRG", "HRS")}


@dataclass
class Corrections:
    """Correction polynomials (Kornus et al. 2006, eq. 2-4); zeros = none.

    position[k, j]: coefficient j (degree j) of the correction of ECEF axis k (m) over the
    normalised time tau = (t - t_centre) / time_scale, t_centre = SpotOrientation.centre_time; the
    orbital frame follows the corrected trajectory. attitude[k, j]: the same for yaw, pitch, roll
    (rad, added to the interpolated angles). look[k, j]: coefficient j of the correction of psi_x
    (k=0) and psi_y (k=1) (rad) over the normalised detector coordinate (p - p_c) / 1000 (p: GDAL
    column coordinate, p_c = ncols / 2). Applied inside the SpotModel kernels at every call."""

    position: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    attitude: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    look: np.ndarray = field(default_factory=lambda: np.zeros((2, 4)))
    time_scale: float = 10.0


@dataclass
class SpotOrientation:
    """Everything the rigorous SPOT 1-5 model needs, as supplied by the producer."""

    mission: int  # MISSION_INDEX, 1..5
    instrument: str  # 'HRV', 'HIR', 'HRG', 'HRS'
    instrument_index: int  # INSTRUMENT_INDEX
    ncols: int
    nrows: int
    epoch: np.datetime64  # UTC reference of all times below (ns precision)
    eph_t: np.ndarray  # (n,) ephemeris times, s since epoch
    eph_pos: np.ndarray  # (n, 3) ECEF position, m
    eph_vel: np.ndarray  # (n, 3) ECEF velocity, m/s
    att_t: np.ndarray  # (m,) attitude sample times, s
    att_ypr: np.ndarray  # (m, 3) yaw, pitch, roll, rad (SPOT 5: corrected; 1-4: raw)
    psi_x: np.ndarray  # (ncols,) look angle psi_x per detector (column), rad
    psi_y: np.ndarray  # (ncols,) look angle psi_y per detector (column), rad
    line_period: float  # s per line
    centre_time: float  # s since epoch of the scene-centre line
    centre_row: float  # GDAL row coordinate of that line's centre
    speed_t: np.ndarray | None = None  # (k,) angular-speed sample times (SPOT 1-4), s
    speed_ypr: np.ndarray | None = None  # (k, 3) yaw/pitch/roll rates, rad/s
    sensor_code: str = ""  # 'P', 'M', 'A', 'J', ...
    mirror_step: int | None = None  # SPOT 1-4 / HRG mirror STEP_COUNT, for information
    corrections: Corrections = field(default_factory=Corrections)
    name: str = ""  # dataset name, for messages

    def validate(self) -> None:
        """Raise MetadataError unless the orientation is complete and physically plausible."""
        where = f"{self.name or 'SPOT scene'}: "

        def fail(what: str, todo: str = "check the METADATA.DIM against the delivered product") -> NoReturn:
            raise MetadataError(f"{where}{what}; {todo}")

        if self.mission not in INSTRUMENTS:
            fail(f"unknown SPOT mission {self.mission!r}", "only SPOT 1 to 5 level-1A scenes are supported")
        if self.instrument not in INSTRUMENTS[self.mission]:
            fail(
                f"instrument {self.instrument!r} does not fly on SPOT {self.mission} "
                f"(expected {' or '.join(INSTRUMENTS[self.mission])})"
            )
        if not (2 <= self.ncols <= MAX_SIZE and 1 <= self.nrows <= MAX_SIZE):
            fail(f"raster size {self.ncols} x {self.nrows} is not the size of a SPOT scene")
        _check_series(fail, "ephemeris", self.eph_t, {"position": self.eph_pos, "velocity": self.eph_vel}, 4)
        radius = np.linalg.norm(self.eph_pos, axis=1)
        speed = np.linalg.norm(self.eph_vel, axis=1)
        if np.any(radius < 6.5e6) or np.any(radius > 5e7) or np.any(speed < 1e3) or np.any(speed > 1.2e4):
            fail(
                "ephemeris are not ECEF metres and metres/second of an Earth orbit "
                f"(|P| {radius.min():.4g}..{radius.max():.4g} m, |V| {speed.min():.4g}..{speed.max():.4g} m/s)"
            )
        _check_series(fail, "attitude", self.att_t, {"yaw/pitch/roll": self.att_ypr}, 1)
        if np.any(np.abs(self.att_ypr) > 0.1):
            fail(
                "platform attitude angles exceed 0.1 rad (SPOT points with its mirror, the platform "
                "stays within a few mrad): are they degrees instead of radians?"
            )
        if self.speed_t is not None:
            _check_series(fail, "angular speed", self.speed_t, {"yaw/pitch/roll rates": self.speed_ypr}, 1)
            if np.any(np.abs(np.asarray(self.speed_ypr)) > 0.01):  # an array: _check_series refuses None
                fail("angular speeds exceed 0.01 rad/s: are they degrees/s instead of rad/s?")
        for label, psi in (("PSI_X", self.psi_x), ("PSI_Y", self.psi_y)):
            psi = np.asarray(psi)
            if psi.shape != (self.ncols,):
                fail(
                    f"{len(psi)} {label} look angles for {self.ncols} detectors",
                    "every detector (column) needs its look angles",
                )
            if not np.all(np.isfinite(psi)) or np.any(np.abs(psi) > 0.8):
                fail(f"{label} look angles must be finite radians within +-0.8")
        step = np.diff(self.psi_y)
        if not (np.all(step > 0) or np.all(step < 0)):
            fail(
                "PSI_Y is not strictly monotone along the detector array",
                "the look-angle table is corrupt or its DETECTOR_IDs are out of order",
            )
        if not (np.isfinite(self.line_period) and 0 < self.line_period < 1):
            fail(f"LINE_PERIOD {self.line_period!r} s is not a line period")
        if not (np.isfinite(self.centre_time) and np.isfinite(self.centre_row)):
            fail("the scene-centre time or line is not a number")
        first, last = float(self.row_time(0.0)), float(self.row_time(float(self.nrows)))
        lo, hi = min(first, last), max(first, last)
        if lo < self.eph_t[0] or hi > self.eph_t[-1]:
            fail(
                f"the ephemeris ({self.eph_t[0]:.3f}..{self.eph_t[-1]:.3f} s) do not cover the acquisition "
                f"({lo:.3f}..{hi:.3f} s)",
                "the orbit must not be extrapolated; use the complete product",
            )

    def row_time(self, row: ArrayLike) -> np.floating | np.ndarray:
        """Acquisition time (s since epoch) of GDAL row coordinate `row`: t = t_c + (row - row_c) T (a numpy
        float for a scalar `row`)."""
        return self.centre_time + (np.asarray(row, dtype=np.float64) - self.centre_row) * self.line_period


def _check_series(
    fail: Callable[..., NoReturn],
    label: str,
    t: ArrayLike,
    values: Mapping[str, np.ndarray | None],
    minimum: int,
) -> None:
    """Times strictly increasing and finite, value arrays (n, 3) finite, at least `minimum` samples."""
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size < minimum:
        fail(f"{t.size if t.ndim == 1 else 0} {label} samples (at least {minimum} needed)")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        fail(f"{label} times are not finite and strictly increasing")
    for name, v in values.items():
        v = np.asarray(v)
        if v.shape != (t.size, 3):
            fail(f"{label} {name} has shape {v.shape}, expected ({t.size}, 3)")
        if not np.all(np.isfinite(v)):
            fail(f"{label} {name} holds values that are not numbers")
