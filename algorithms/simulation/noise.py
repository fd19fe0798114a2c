"""Deterministic procedural noise for numba kernels: integer hashing, 2-D gradient noise,
fractional Brownian motion and jittered-grid cellular (Worley) noise.

Everything is a pure function of the coordinates and an integer seed (no global state), so a
kernel evaluated in parallel gives the same bytes whatever the thread schedule. Coordinates are in
"noise units": the lattice spacing is 1 (scale metres by the wanted feature size)."""

import math

import numpy as np
from numba import njit

_MASK = 0xFFFFFFFF
#: 8 unit gradient directions of the gradient noise
_GRAD = np.array([[math.cos(k * math.pi / 4.0), math.sin(k * math.pi / 4.0)] for k in range(8)])


@njit(cache=True, nogil=True)
def hash3(a, b, c):
    """32-bit integer hash of three integers (multiply-xorshift mixing), as int64 in [0, 2^32)."""
    h = (a * 374761393 + b * 668265263 + c * 2147483647 + 1013904223) & _MASK
    h = ((h ^ (h >> 15)) * 2246822519) & _MASK
    h = ((h ^ (h >> 13)) * 3266489917) & _MASK
    return h ^ (h >> 16)


@njit(cache=True, nogil=True)
def uniform(a, b, c):
    """Hash of (a, b, c) as a float in [0, 1)."""
    return hash3(a, b, c) / 4294967296.0


@njit(cache=True, nogil=True)
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@njit(cache=True, nogil=True)
def _corner(ix, iy, seed, dx, dy):
    k = hash3(ix, iy, seed) & 7
    return _GRAD[k, 0] * dx + _GRAD[k, 1] * dy


@njit(cache=True, nogil=True)
def gradient_noise(x, y, seed):
    """Perlin gradient noise: sum of the corner gradients' dot products with the offsets,
    blended by the quintic fade 6t^5 - 15t^4 + 10t^3. Zero on lattice points, |value| < 1."""
    fx = math.floor(x)
    fy = math.floor(y)
    ix = int(fx)
    iy = int(fy)
    dx = x - fx
    dy = y - fy
    u = _fade(dx)
    v = _fade(dy)
    n00 = _corner(ix, iy, seed, dx, dy)
    n10 = _corner(ix + 1, iy, seed, dx - 1.0, dy)
    n01 = _corner(ix, iy + 1, seed, dx, dy - 1.0)
    n11 = _corner(ix + 1, iy + 1, seed, dx - 1.0, dy - 1.0)
    return (n00 * (1.0 - u) + n10 * u) * (1.0 - v) + (n01 * (1.0 - u) + n11 * u) * v


@njit(cache=True, nogil=True)
def fbm(x, y, seed, octaves, persistence):
    """Fractional Brownian motion: sum_k persistence^k * noise(2^k x, 2^k y), k < octaves,
    normalised by sum_k persistence^k (so |value| < 1)."""
    total = 0.0
    norm = 0.0
    amp = 1.0
    freq = 1.0
    for k in range(octaves):
        total += amp * gradient_noise(x * freq, y * freq, seed + 7919 * k)
        norm += amp
        amp *= persistence
        freq *= 2.0
    return total / norm


@njit(cache=True, nogil=True)
def worley(x, y, seed, jitter):
    """Jittered-grid cellular noise: the nearest feature point, one per unit cell at
    (ix + 0.5 + jitter (u - 0.5), iy + ...), u uniform from the hash.

    Returns (distance to the nearest point, its cell ix, its cell iy, distance to the second
    nearest point); the cell identifies the parcel / tree crown the point belongs to."""
    cx = int(math.floor(x))
    cy = int(math.floor(y))
    best = 1e30
    second = 1e30
    bx = cx
    by = cy
    for j in range(cy - 1, cy + 2):
        for i in range(cx - 1, cx + 2):
            px = i + 0.5 + jitter * (uniform(i, j, seed) - 0.5)
            py = j + 0.5 + jitter * (uniform(i, j, seed + 1) - 0.5)
            d = math.hypot(x - px, y - py)
            if d < best:
                second = best
                best = d
                bx = i
                by = j
            elif d < second:
                second = d
    return best, bx, by, second
