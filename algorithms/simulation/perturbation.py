"""Known errors of the supplied orientation, in the Corrections convention (spot_orientation.py):
truth = supplied + correction polynomials, so an adjustment of the supplied orientation should
estimate exactly these coefficients.

- Look angles: the correction polynomials Kornus et al. 2006 estimated, Table 2, with random signs.
  Kornus et al.'s "x" coefficients act in the scan direction, i.e. on psi_y (Corrections.look[1]); its "y"
  ones in the flight direction, on psi_x (look[0]). SPOT 1-4 arrays keep degree <= 1 (their
  DIMAP look-angle table is linear).
- Exterior orientation, common to the trajectory of a pass (so the images of one pass share it):
  a constant ECEF position bias of 8 m, attitude biases N(0, 15 urad) (pitch, roll) and
  N(0, 20 urad) (yaw), and attitude drifts N(0, 1 urad per 10 s). Re-expanded per image about
  its own centre time: a0 = bias + drift (t_c,image - t_ref) / time_scale, a1 = drift.
Together they displace the ground by about 30 m, the accuracy K found for the supplied data."""

import numpy as np

from ..sensors.spot_orientation import Corrections

#: Kornus et al. 2006, Table 2 (x: scan -> psi_y, y: flight -> psi_x), coefficients A, B, C, D
TABLE2 = {
    "HRG": {"psi_x": (2.8e-5, 0.0, 0.0, 0.0), "psi_y": (5.3e-6, 1.0e-6, 0.0, 0.0)},
    "HRS1": {"psi_x": (1.5e-5, 0.0, -4.2e-7, -6.9e-8), "psi_y": (-4.9e-6, 0.0, 0.0, 0.0)},
    "HRS2": {"psi_x": (0.0, 0.0, -4.6e-7, -7.4e-8), "psi_y": (0.0, 0.0, 0.0, 0.0)},
}
POSITION_BIAS = 8.0  # m
ATTITUDE_BIAS = np.array([20e-6, 15e-6, 15e-6])  # rad, yaw, pitch, roll (1 sigma)
ATTITUDE_DRIFT = 1e-6  # rad per time_scale (1 sigma)


def _table_row(instrument):
    if instrument.instrument == "HRS":
        return TABLE2[f"HRS{instrument.instrument_index}"]
    return TABLE2["HRG"]


def inject(images, rng, scale=1.0):
    """Corrections (per image name) and the trajectory errors of each pass, all times `scale`."""
    time_scale = Corrections().time_scale
    corrections, passes = {}, {}
    for image in images:
        key = image.instrument.pass_index
        if key not in passes:
            direction = rng.normal(size=3)
            passes[key] = {
                "t_ref": image.centre_time,
                "position_bias": scale * POSITION_BIAS * direction / np.linalg.norm(direction),
                "attitude_bias": scale * rng.normal(0.0, ATTITUDE_BIAS),
                "attitude_drift": scale * rng.normal(0.0, ATTITUDE_DRIFT, 3),
            }
        p = passes[key]
        row = _table_row(image.instrument)
        look = np.array([row["psi_x"], row["psi_y"]]) * rng.choice([-1.0, 1.0], (2, 4)) * scale
        if image.instrument.mission < 5:
            look[:, 2:] = 0.0
        position = np.zeros((3, 4))
        position[:, 0] = p["position_bias"]
        attitude = np.zeros((3, 4))
        attitude[:, 0] = p["attitude_bias"] + p["attitude_drift"] * (image.centre_time - p["t_ref"]) / time_scale
        attitude[:, 1] = p["attitude_drift"]
        corrections[image.name] = Corrections(position=position, attitude=attitude, look=look, time_scale=time_scale)
    return corrections, passes
