"""Frames and rotations of the SPOT Satellite Geometry Handbook (SPOT 1-5 level 1A).

A detector's line of sight goes through three frames:

- navigation frame (O1): look direction u1 = (-tan psi_y, tan psi_x, -1) (handbook "viewing
  direction"; NOT normalised here: its third component is -1). psi_y is the across-track look
  angle (varies along the array), psi_x the along-track one.
- local orbital frame (O2): Z2 = P/|P| (radial, up), X2 = (V x P)/|V x P| (normal to the orbital
  plane, across track), Y2 = Z2 x X2 (along track, forward); P, V are the ECEF position and
  velocity. u2 = R21 u1 with R21 = Rx(-pitch) Ry(-roll) Rz(yaw) (active rotations).
  The handbook gives the attitude angles in the frame (O1, -X1, -Y1, Z1), hence the sign
  change of pitch (about X) and roll (about Y); yaw is applied first.
- ECEF (O3): u3 = R32 u2, R32 = [X2 Y2 Z2] (columns).

So the ground point is X = P + mu * R32 R21 u1.

These are the conventions the producer used: its scene corners are reproduced, and flipping a sign or
the order of the rotations is not (docs/validation.md#spot-producer-corners;
tests/real/test_spot_dimap.py::test_frame_convention_is_the_one_the_producer_used).

Rotations are returned as row-major 9-tuples (no allocation inside numba kernels); `r21` and
`r32` give numpy 3 x 3 arrays for Python callers (the simulator, tests). Kernels use numba's
"numpy" error model: degenerate input gives inf/NaN, never a ZeroDivisionError.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: a 3 x 3 rotation as a row-major 9-tuple
Rotation = tuple[float, float, float, float, float, float, float, float, float]
#: a vector (x, y, z)
Vector = tuple[float, float, float]


@njit(cache=True, nogil=True, error_model="numpy")
def look_vector(psi_x: float, psi_y: float) -> Vector:
    """Navigation-frame look direction u1 = (-tan psi_y, tan psi_x, -1) (not normalised)."""
    return -math.tan(psi_y), math.tan(psi_x), -1.0


@njit(cache=True, nogil=True, error_model="numpy")
def look_angles(x: float, y: float, z: float) -> tuple[float, float]:
    """Inverse of `look_vector` for a navigation-frame direction (x, y, z) with z < 0:
    psi_x = atan(-y / z), psi_y = atan(x / z)."""
    return math.atan(-y / z), math.atan(x / z)


@njit(cache=True, nogil=True, error_model="numpy")
def attitude_rotation(yaw: float, pitch: float, roll: float) -> Rotation:
    """R21 (navigation -> local orbital frame) = Rx(-pitch) Ry(-roll) Rz(yaw), row-major 9-tuple.

    Angles in radians as given in DIMAP (Corrected_Attitudes or integrated Raw_Attitudes)."""
    cx, sx = math.cos(pitch), -math.sin(pitch)
    cy, sy = math.cos(roll), -math.sin(roll)
    cz, sz = math.cos(yaw), math.sin(yaw)
    # Ry Rz
    a00, a01, a02 = cy * cz, -cy * sz, sy
    a10, a11, a12 = sz, cz, 0.0
    a20, a21, a22 = -sy * cz, sy * sz, cy
    # Rx (Ry Rz)
    return (
        a00,
        a01,
        a02,
        cx * a10 - sx * a20,
        cx * a11 - sx * a21,
        cx * a12 - sx * a22,
        sx * a10 + cx * a20,
        sx * a11 + cx * a21,
        sx * a12 + cx * a22,
    )


@njit(cache=True, nogil=True, error_model="numpy")
def orbital_rotation(px: float, py: float, pz: float, vx: float, vy: float, vz: float) -> Rotation:
    """R32 (local orbital frame -> ECEF), row-major 9-tuple whose columns are
    X2 = (V x P)/|V x P|, Y2 = Z2 x X2, Z2 = P/|P|."""
    n = math.sqrt(px * px + py * py + pz * pz)
    zx, zy, zz = px / n, py / n, pz / n
    xx, xy, xz = vy * pz - vz * py, vz * px - vx * pz, vx * py - vy * px
    n = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / n, xy / n, xz / n
    yx, yy, yz = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx
    return (xx, yx, zx, xy, yy, zy, xz, yz, zz)


@njit(cache=True, nogil=True, error_model="numpy")
def mat_vec(m: Rotation, x: float, y: float, z: float) -> Vector:
    """m (row-major 9-tuple) times (x, y, z)."""
    return (m[0] * x + m[1] * y + m[2] * z, m[3] * x + m[4] * y + m[5] * z, m[6] * x + m[7] * y + m[8] * z)


@njit(cache=True, nogil=True, error_model="numpy")
def mat_t_vec(m: Rotation, x: float, y: float, z: float) -> Vector:
    """Transpose of m (row-major 9-tuple) times (x, y, z): the inverse rotation."""
    return (m[0] * x + m[3] * y + m[6] * z, m[1] * x + m[4] * y + m[7] * z, m[2] * x + m[5] * y + m[8] * z)


@njit(cache=True, nogil=True, error_model="numpy")
def mat_mul(a: Rotation, b: Rotation) -> Rotation:
    """Product a b of two row-major 9-tuples."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@njit(cache=True, nogil=True, error_model="numpy")
def look_direction_ecef(
    psi_x: float,
    psi_y: float,
    yaw: float,
    pitch: float,
    roll: float,
    px: float,
    py: float,
    pz: float,
    vx: float,
    vy: float,
    vz: float,
) -> Vector:
    """Unit ECEF look direction R32 R21 u1 of a detector with look angles (psi_x, psi_y)."""
    ux, uy, uz = look_vector(psi_x, psi_y)
    ux, uy, uz = mat_vec(attitude_rotation(yaw, pitch, roll), ux, uy, uz)
    ux, uy, uz = mat_vec(orbital_rotation(px, py, pz, vx, vy, vz), ux, uy, uz)
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    return ux / n, uy / n, uz / n


@njit(cache=True, nogil=True, error_model="numpy")
def ecef_to_look_angles(
    dx: float,
    dy: float,
    dz: float,
    yaw: float,
    pitch: float,
    roll: float,
    px: float,
    py: float,
    pz: float,
    vx: float,
    vy: float,
    vz: float,
) -> tuple[float, float]:
    """Look angles (psi_x, psi_y) of the ECEF direction (dx, dy, dz) seen from the satellite:
    u1 ~ R21^T R32^T d (inverse of `look_direction_ecef`)."""
    x, y, z = mat_t_vec(orbital_rotation(px, py, pz, vx, vy, vz), dx, dy, dz)
    x, y, z = mat_t_vec(attitude_rotation(yaw, pitch, roll), x, y, z)
    return look_angles(x, y, z)


@njit(cache=True, nogil=True, error_model="numpy")
def _as_array(m: Rotation) -> np.ndarray:
    out = np.empty((3, 3))
    for i in range(9):
        out[i // 3, i % 3] = m[i]
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def r21(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """R21 as a 3 x 3 array (see `attitude_rotation`)."""
    return _as_array(attitude_rotation(yaw, pitch, roll))


@njit(cache=True, nogil=True, error_model="numpy")
def r32(px: float, py: float, pz: float, vx: float, vy: float, vz: float) -> np.ndarray:
    """R32 as a 3 x 3 array (see `orbital_rotation`)."""
    return _as_array(orbital_rotation(px, py, pz, vx, vy, vz))
