"""A small synthetic SPOT orientation for tests that must not depend on the real data: a circular
sun-synchronous orbit seen from the rotating Earth, smooth attitude, a wide look-angle table."""

import numpy as np

from pushbroom.algorithms.geodesy import OMEGA_EARTH
from pushbroom.algorithms.sensors.spot_orientation import SpotOrientation

GM = 3.986004418e14


def orbit(t, radius=7.2e6, inclination=np.radians(98.7), node=np.radians(20.0), phase=np.radians(40.0)):
    """ECEF position and velocity (n, 3) of a circular orbit at times t (s)."""
    n = np.sqrt(GM / radius**3)
    u = phase + n * t
    ci, si, cn, sn = np.cos(inclination), np.sin(inclination), np.cos(node), np.sin(node)
    p_in = radius * np.column_stack(
        [cn * np.cos(u) - sn * ci * np.sin(u), sn * np.cos(u) + cn * ci * np.sin(u), si * np.sin(u)]
    )
    v_in = (
        radius
        * n
        * np.column_stack(
            [-cn * np.sin(u) - sn * ci * np.cos(u), -sn * np.sin(u) + cn * ci * np.cos(u), si * np.cos(u)]
        )
    )
    a = -OMEGA_EARTH * t
    ca, sa = np.cos(a), np.sin(a)
    rot = lambda v: np.column_stack([ca * v[:, 0] - sa * v[:, 1], sa * v[:, 0] + ca * v[:, 1], v[:, 2]])
    pos = rot(p_in)
    vel = rot(v_in) - OMEGA_EARTH * np.column_stack([-pos[:, 1], pos[:, 0], np.zeros(len(t))])
    return pos, vel


def synthetic_orientation(mission=5, ncols=300, nrows=200, look_rows=None):
    """A SPOT `mission` orientation of a ncols x nrows scene (about 60 km wide, 5 s long).

    SPOT 1-4 variants carry raw angles and angular speeds; `look_rows` unused detectors are
    interpolated like DIMAP's first/last table."""
    eph_t = np.arange(-150.0, 151.0, 30.0)
    pos, vel = orbit(eph_t)
    line_period = 5.0 / nrows
    att_t = np.arange(-4.0, 4.01, 0.125)
    ypr = np.column_stack([3e-4 + 2e-5 * np.sin(att_t), -2e-4 + 1e-5 * att_t, 1e-4 * np.cos(0.5 * att_t)])
    det = np.arange(ncols)
    psi_y = np.radians(-2.06) + det * (np.radians(4.12) / (ncols - 1)) + 1e-4 * np.sin(det / ncols * 3)
    psi_x = 2e-3 + 1e-5 * (det / ncols) ** 2
    kwargs = {}
    if mission <= 4:
        speed_t = np.arange(-3.0, 3.01, 0.125)
        kwargs = dict(
            speed_t=speed_t,
            speed_ypr=np.column_stack([1e-6 * np.cos(speed_t), -3e-6 + 0 * speed_t, 2e-6 * np.sin(speed_t)]),
            mirror_step=48,
        )
        att_t = np.array([-3.2, 3.1])
        ypr = np.array([[1e-6, 2e-6, -1e-6], [1.5e-6, -1e-6, 0.0]])
        psi_x = np.linspace(psi_x[0], psi_x[-1], ncols)
        psi_y = np.linspace(psi_y[0], psi_y[-1], ncols)
    instrument = {5: "HRG", 4: "HIR"}.get(mission, "HRV")
    return SpotOrientation(
        mission=mission,
        instrument=instrument,
        instrument_index=1,
        ncols=ncols,
        nrows=nrows,
        epoch=np.datetime64("2005-03-13T05:21:00", "ns"),
        eph_t=eph_t,
        eph_pos=pos,
        eph_vel=vel,
        att_t=att_t,
        att_ypr=ypr,
        psi_x=psi_x,
        psi_y=psi_y,
        line_period=line_period,
        centre_time=0.25,
        centre_row=nrows / 2,
        sensor_code="A" if mission == 5 else "P",
        name=f"synthetic SPOT {mission}",
        **kwargs,
    )
