"""The platform's true motion, analytic in time so the truth is continuous (never interpolated):
a sun-synchronous circular orbit in ECEF, and a smoothly drifting attitude.

Orbit: uniform circular motion of radius a at the Keplerian rate n = sqrt(GM / a^3) in a plane of
inclination i whose node precesses at the J2 rate dOmega/dt = -3/2 n J2 (R/a)^2 cos i, chosen
equal to the Earth's mean motion around the sun (sun-synchronous: i = 98.7 deg for a = 7200.5 km,
about 822-832 km above the ellipsoid). In ECEF the node longitude moves at
dlambda/dt = dOmega/dt - omega_earth, so with argument of latitude u(t) = u0 + n (t - t0):

    P(t) = a R3(lambda(t)) R1(i) (cos u, sin u, 0),   V(t) = dP/dt (analytic).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import GeometryError
from ..geodesy import OMEGA_EARTH, A
from ..sensors import spot_frames

GM = 3.986004418e14  # m^3/s^2, WGS 84
J2 = 1.08262668e-3
SUN_RATE = 2.0 * math.pi / (365.2422 * 86400.0)  # rad/s, mean motion of the sun
SPOT_SEMI_MAJOR_AXIS = 7200.5e3  # m (Orbital_Bulletin ELLIPSE_AXIS of SPOT 2 and 5)


def sun_synchronous_inclination(a):
    """Inclination (rad) at which the J2 node precession equals the sun's mean motion."""
    n = math.sqrt(GM / a**3)
    return math.acos(-SUN_RATE / (1.5 * n * J2 * (A / a) ** 2))


@dataclass(frozen=True)
class CircularOrbit:
    """Circular sun-synchronous orbit; node longitude `node_lon` and argument of latitude `u0`
    (rad) at time `t0` (s since the image epoch)."""

    node_lon: float
    u0: float
    t0: float
    a: float = SPOT_SEMI_MAJOR_AXIS

    @property
    def inclination(self):
        return sun_synchronous_inclination(self.a)

    @property
    def mean_motion(self):
        return math.sqrt(GM / self.a**3)

    def state(self, t):
        """ECEF position (m) and velocity (m/s), arrays (..., 3), at times t (s)."""
        dt = np.asarray(t, dtype=np.float64) - self.t0
        u = self.u0 + self.mean_motion * dt
        lam_rate = SUN_RATE - OMEGA_EARTH
        lam = self.node_lon + lam_rate * dt
        ci, si = math.cos(self.inclination), math.sin(self.inclination)
        cu, su, cl, sl = np.cos(u), np.sin(u), np.cos(lam), np.sin(lam)
        pos = self.a * np.stack([cu * cl - su * ci * sl, cu * sl + su * ci * cl, su * si], axis=-1)
        du = self.mean_motion * np.stack([-su * cl - cu * ci * sl, -su * sl + cu * ci * cl, cu * si], axis=-1)
        dl = lam_rate * np.stack([-cu * sl - su * ci * cl, cu * cl - su * ci * sl, np.zeros_like(u)], axis=-1)
        return pos, self.a * (du + dl)


@dataclass(frozen=True)
class Attitude:
    """Yaw, pitch, roll (rad) = bias + sum_k amplitude_k sin(2 pi (t - t0) / period_k + phase_k):
    a constant pointing offset plus a slow, smooth drift (arrays (3,), (3, K))."""

    bias: np.ndarray
    amplitude: np.ndarray
    period: np.ndarray
    phase: np.ndarray
    t0: float

    @classmethod
    def random(cls, rng, t0, bias_sigma=5e-4, drift=2e-5, terms=2):
        """Biases ~ N(0, bias_sigma) (real SPOT 5 corrected attitudes are 1e-4..1e-3 rad),
        `terms` drift sinusoids per axis of amplitude drift/2..drift and period 20-120 s."""
        return cls(
            rng.normal(0.0, bias_sigma, 3),
            rng.uniform(0.5 * drift, drift, (3, terms)),
            rng.uniform(20.0, 120.0, (3, terms)),
            rng.uniform(0.0, 2 * math.pi, (3, terms)),
            float(t0),
        )

    def angles(self, t):
        """(..., 3) yaw, pitch, roll at times t."""
        w = 2 * math.pi / self.period
        arg = w[None] * (np.asarray(t, dtype=np.float64).reshape(-1, 1, 1) - self.t0) + self.phase[None]
        out = self.bias[None] + np.sum(self.amplitude[None] * np.sin(arg), axis=-1)
        return out.reshape(np.shape(t) + (3,))

    def rates(self, t):
        """(..., 3) yaw, pitch, roll angular speeds (rad/s), the analytic derivative of `angles`."""
        w = 2 * math.pi / self.period
        arg = w[None] * (np.asarray(t, dtype=np.float64).reshape(-1, 1, 1) - self.t0) + self.phase[None]
        out = np.sum((self.amplitude * w)[None] * np.cos(arg), axis=-1)
        return out.reshape(np.shape(t) + (3,))


def look_residual(orbit, attitude, t, target, psi_x, psi_y):
    """Look angles of `target` (ECEF) seen at time t minus (psi_x, psi_y), rad."""
    pos, vel = orbit.state(t)
    yaw, pitch, roll = attitude.angles(t)
    d = np.asarray(target) - pos
    seen = spot_frames.ecef_to_look_angles(d[0], d[1], d[2], yaw, pitch, roll, *pos, *vel)
    return np.array([seen[0] - psi_x, seen[1] - psi_y])


def newton(residual, x, steps, tol, what):
    """Newton's method with a forward-difference Jacobian (`steps`) on a 2-vector, until every
    |update| < tol (absolute, per component)."""
    for _ in range(50):
        f = residual(x)
        jac = np.column_stack([(residual(x + dx) - f) / dx[k] for k, dx in enumerate(np.diag(steps))])
        delta = np.linalg.solve(jac, -f)
        x = x + delta
        if np.all(np.abs(delta) < tol):
            return x
    raise GeometryError(f"the simulator could not solve the {what}")


def orbit_through(target, t0, attitude, psi_x, psi_y):
    """The descending circular orbit from which the detector with look angles (psi_x, psi_y)
    sees the ECEF point `target` at time t0 (solves node longitude and u0 by Newton)."""
    x, y, z = target
    a = SPOT_SEMI_MAJOR_AXIS
    inc = sun_synchronous_inclination(a)
    lat = math.atan2(z, math.hypot(x, y))
    u = math.pi - math.asin(math.sin(lat) / math.sin(inc))
    node = math.atan2(y, x) - math.atan2(math.cos(inc) * math.sin(u), math.cos(u))

    def residual(p):
        return look_residual(CircularOrbit(p[0], p[1], t0, a), attitude, t0, target, psi_x, psi_y)

    node, u = newton(
        residual, np.array([node, u]), np.array([1e-7, 1e-7]), np.array([1e-13, 1e-13]), "orbit over the scene"
    )
    return CircularOrbit(float(node), float(u), float(t0), a)


def time_and_roll(orbit, attitude, target, psi_x, t_guess):
    """(t, psi_y) at which a detector of along-track angle psi_x sees `target` (psi_y from 0)."""

    def residual(p):
        return look_residual(orbit, attitude, p[0], target, psi_x, p[1])

    t, psi_y = newton(
        residual,
        np.array([t_guess, 0.0]),
        np.array([1e-3, 1e-7]),
        np.array([1e-9, 1e-13]),
        "acquisition time of the scene centre",
    )
    return float(t), float(psi_y)
