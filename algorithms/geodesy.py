"""WGS 84 geodesy used inside numba kernels: geodetic <-> ECEF.

Longitude/latitude in degrees, ellipsoidal height in metres (EPSG:4979); ECEF in metres
(EPSG:4978). Tested against PROJ to the millimetre (tests/algorithms/test_geodesy.py).
ECEF -> geodetic uses Bowring's start value and Newton-refined latitude (Heikkinen-type closed
forms lose precision near the poles; this form is exact to < 1e-9 m for |h| < 1e5 km)."""

import math

import numpy as np
from numba import njit

from .errors import InputError

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


@njit(cache=True, nogil=True, error_model="numpy")
def bowring(p, z):
    """Geodetic (cos lat, sin lat, h) of a point at distance p from the polar axis and height z above
    the equator plane: Bowring's formula, one step without trigonometry (error < 1e-6 m in
    latitude and 1e-8 m in height for |h| < 10 km, 1e-4 m at 100 km)."""
    r = math.hypot(z * A, p * B)
    st, ct = z * A / r, p * B / r
    num = z + EP2 * B * st * st * st
    den = p - E2 * A * ct * ct * ct
    n = math.hypot(num, den)
    cl, sl = den / n, num / n
    return cl, sl, p * cl + z * sl - A * math.sqrt(1.0 - E2 * sl * sl)


@njit(cache=True, nogil=True)
def ecef_to_geodetic_scalar(x, y, z):
    """(X, Y, Z) -> (lon, lat, h) with Bowring's start and three Newton steps on latitude."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    if p < 1e-9:
        lat = math.copysign(math.pi / 2.0, z)
        return math.degrees(lon), math.degrees(lat), abs(z) - B
    cl, sl, _ = bowring(p, z)
    lat = math.atan2(sl, cl)
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


def flat_points(*values):
    """Broadcast point coordinates to writable, contiguous float64 1-D arrays for the kernels.

    Returns (arrays, shape, scalar): the broadcast shape, and whether all inputs were scalars.
    Raises InputError for values that are not real numbers or shapes that do not broadcast."""
    try:
        arrays = [np.asarray(v, dtype=np.float64) for v in values]
        shape = np.broadcast_shapes(*(a.shape for a in arrays))
    except (TypeError, ValueError) as exc:
        raise InputError(f"point coordinates must be real numbers or arrays of one shape ({exc})") from None
    flat = [
        a.ravel()
        if a.shape == shape and a.flags.c_contiguous and a.flags.writeable
        else np.broadcast_to(a, shape).flatten()
        for a in arrays
    ]
    return flat, shape, len(shape) == 0


def geodetic_to_ecef(lon, lat, h):
    """Arrays (any broadcastable shape) -> ECEF array of shape (..., 3)."""
    (lon, lat, h), shape, _ = flat_points(lon, lat, h)
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


def radii(lat):
    """Prime-vertical and meridian radii of curvature (N, M) at latitude `lat` (degrees, scalar or array):
    N = a / w, M = a (1 - e^2) / w^3, w = sqrt(1 - e^2 sin^2(lat))."""
    s = np.sin(np.radians(lat))
    w = np.sqrt(1.0 - E2 * s * s)
    return A / w, A * (1.0 - E2) / w**3


def metres_per_degree(lat, h=0.0):
    """(east, north) metres per degree of longitude and latitude at `lat` and ellipsoidal height h:
    ((N + h) cos(lat), M + h) pi / 180."""
    n, m = radii(lat)
    return (n + h) * np.cos(np.radians(lat)) * math.pi / 180.0, (m + h) * math.pi / 180.0


def offset_enu(lon, lat, h, d):
    """Points moved by d (n, 3: metres east, north, up), to first order: lon + dE / (m per degree
    of longitude), lat + dN / (m per degree of latitude), h + dU; NaN rows of d leave points as they are."""
    e_deg, n_deg = metres_per_degree(lat, h)
    d = np.nan_to_num(d)
    return lon + d[:, 0] / e_deg, lat + d[:, 1] / n_deg, h + d[:, 2]


def utm_epsg(lon, lat):
    """EPSG code of the WGS 84 UTM zone containing (lon, lat)."""
    zone = int(math.floor((lon + 180.0) / 6.0)) % 60 + 1
    return (32600 if lat >= 0 else 32700) + zone
