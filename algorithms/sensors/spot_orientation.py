"""The supplied orientation of one SPOT level-1A scene, in the engine's conventions.

This is the contract between the DIMAP reader/writer (`dimap.py`), the rigorous model
(`spot.py`) and the simulator: times are seconds since `epoch` (UTC), angles radians, positions
ECEF metres, pixel coordinates in GDAL's convention. The DIMAP 1-based pixel-centre convention is
converted at the reader: DIMAP line L (1-based, centre) is GDAL row L - 0.5, detector D (1-based)
looks through column centre D - 0.5.
"""
from dataclasses import dataclass, field
from typing import Optional

import numpy as np


@dataclass
class Corrections:
    """Correction polynomials of methods.md section 4 (paper 000 eq. 2-4); zeros = none.

    position[k, j]: coefficient j (degree j) of the correction of ECEF axis k over the normalised
    time tau = (t - t_centre) / time_scale. attitude[k, j]: the same for yaw, pitch, roll (rad).
    look[k, j]: coefficient j of the correction of psi_x (k=0) and psi_y (k=1) over the normalised
    detector coordinate (p - p_c) / 1000 (p: column, p_c: centre column)."""

    position: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    attitude: np.ndarray = field(default_factory=lambda: np.zeros((3, 4)))
    look: np.ndarray = field(default_factory=lambda: np.zeros((2, 4)))
    time_scale: float = 10.0


@dataclass
class SpotOrientation:
    """Everything the rigorous SPOT 1-5 model needs, as supplied by the producer."""

    mission: int                      # MISSION_INDEX, 1..5
    instrument: str                   # 'HRV', 'HIR', 'HRG', 'HRS'
    instrument_index: int             # INSTRUMENT_INDEX
    ncols: int
    nrows: int
    epoch: np.datetime64              # UTC reference of all times below (ns precision)
    eph_t: np.ndarray                 # (n,) ephemeris times, s since epoch
    eph_pos: np.ndarray               # (n, 3) ECEF position, m
    eph_vel: np.ndarray               # (n, 3) ECEF velocity, m/s
    att_t: np.ndarray                 # (m,) attitude sample times, s
    att_ypr: np.ndarray               # (m, 3) yaw, pitch, roll, rad (SPOT 5: corrected; 1-4: raw)
    psi_x: np.ndarray                 # (ncols,) look angle psi_x per detector (column), rad
    psi_y: np.ndarray                 # (ncols,) look angle psi_y per detector (column), rad
    line_period: float                # s per line
    centre_time: float                # s since epoch of the scene-centre line
    centre_row: float                 # GDAL row coordinate of that line's centre
    speed_t: Optional[np.ndarray] = None    # (k,) angular-speed sample times (SPOT 1-4), s
    speed_ypr: Optional[np.ndarray] = None  # (k, 3) yaw/pitch/roll rates, rad/s
    sensor_code: str = ""             # 'P', 'M', 'A', 'J', ...
    mirror_step: Optional[int] = None  # SPOT 1-4 / HRG mirror STEP_COUNT, for information
    corrections: Corrections = field(default_factory=Corrections)
    name: str = ""                    # dataset name, for messages

    def row_time(self, row):
        """Acquisition time (s since epoch) of GDAL row coordinate `row`: t = t_c + (row - row_c) T."""
        return self.centre_time + (np.asarray(row, dtype=np.float64) - self.centre_row) * self.line_period
