"""WGS 84 geodesy used inside numba kernels: geodetic <-> ECEF.

Longitude/latitude in degrees, ellipsoidal height in metres (EPSG:4979); ECEF in metres
(EPSG:4978). Tested against PROJ to the millimetre (tests/algorithms/test_geodesy.py).
ECEF -> geodetic uses Bowring's start value and Newton-refined latitude (Heikkinen-type closed
forms lose precision near the poles; this form is exact to < 1e-9 m for |h| < 1e5 km)."""
import math

import numpy as np
from numba import njit

A = 6378137.0
F = 1.0 / 298.257223563
B = A * (1.0 - F)
E2 = F * (2.0 - F)
EP2 = E2 / (1.0 - E2)
OMEGA_EARTH = 7.292115e-5  # rad/s, WGS 84 Earth rotation rate


@njit(cache=True, nogil=True)
def geodetic_to_ecef_scalar(lon_deg, lat_deg, h):
    """(lon, lat, h) -> (X, Y, Z): X = (N + h) cos(lat) cos(lon), ..., Z = (N (1 - e^2) + h) sin(lat)."""
    lon = math.radians(lon_deg)
    lat = math.radians(lat_deg)
    s = math.sin(lat)
    c = math.cos(lat)
    n = A / math.sqrt(1.0 - E2 * s * s)
    return (n + h) * c * math.cos(lon), (n + h) * c * math.sin(lon), (n * (1.0 - E2) + h) * s


@njit(cache=True, nogil=True)
def ecef_to_geodetic_scalar(x, y, z):
    """(X, Y, Z) -> (lon, lat, h) with Bowring's start and two Newton steps on latitude."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    if p < 1e-9:
        lat = math.copysign(math.pi / 2.0, z)
        return math.degrees(lon), math.degrees(lat), abs(z) - B
    theta = math.atan2(z * A, p * B)
    st = math.sin(theta)
    ct = math.cos(theta)
    lat = math.atan2(z + EP2 * B * st * st * st, p - E2 * A * ct * ct * ct)
    for _ in range(3):
        s = math.sin(lat)
        n = A / math.sqrt(1.0 - E2 * s * s)
        lat = math.atan2(z + n * E2 * s, p)
    s = math.sin(lat)
    c = math.cos(lat)
    n = A / math.sqrt(1.0 - E2 * s * s)
    if abs(c) > 1e-3:
        h = p / c - n
    else:
        h = z / s - n * (1.0 - E2)
    return math.degrees(lon), math.degrees(lat), h


@njit(cache=True, nogil=True)
def _geodetic_to_ecef_arrays(lon, lat, h, out):
    for i in range(lon.size):
        out[i, 0], out[i, 1], out[i, 2] = geodetic_to_ecef_scalar(lon[i], lat[i], h[i])


@njit(cache=True, nogil=True)
def _ecef_to_geodetic_arrays(xyz, out):
    for i in range(xyz.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = ecef_to_geodetic_scalar(xyz[i, 0], xyz[i, 1], xyz[i, 2])


def geodetic_to_ecef(lon, lat, h):
    """Arrays (any broadcastable shape) -> ECEF array of shape (..., 3)."""
    arrays = [np.asarray(v, dtype=np.float64) for v in (lon, lat, h)]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    lon, lat, h = (np.broadcast_to(a, shape).flatten() for a in arrays)
    out = np.empty((lon.size, 3))
    _geodetic_to_ecef_arrays(lon, lat, h, out)
    return out.reshape(shape + (3,))


def ecef_to_geodetic(xyz):
    """ECEF array (..., 3) -> (lon, lat, h) arrays of shape (...)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    flat = np.ascontiguousarray(xyz.reshape(-1, 3))
    out = np.empty_like(flat)
    _ecef_to_geodetic_arrays(flat, out)
    shape = xyz.shape[:-1]
    return out[:, 0].reshape(shape), out[:, 1].reshape(shape), out[:, 2].reshape(shape)


def utm_epsg(lon, lat):
    """EPSG code of the WGS 84 UTM zone containing (lon, lat)."""
    zone = int(math.floor((lon + 180.0) / 6.0)) % 60 + 1
    return (32600 if lat >= 0 else 32700) + zone
