"""Solar position (NOAA / Meeus low-precision algorithm, about 0.01 deg from 1950 to 2050)."""

import math

import numpy as np


def sun_position(time_utc, lon, lat):
    """(azimuth, elevation) in degrees of the sun seen from (lon, lat) at `time_utc`
    (np.datetime64, UTC). Azimuth clockwise from north; elevation without refraction.

    Mean longitude L0 and anomaly M of the sun, equation of centre C -> apparent longitude
    lambda; declination asin(sin(eps) sin(lambda)); equation of time from L0, M, eccentricity and
    y = tan^2(eps/2); hour angle from the true solar time."""
    days = (np.datetime64(time_utc, "ns") - np.datetime64("2000-01-01T12:00:00", "ns")) / np.timedelta64(1, "D")
    t = float(days) / 36525.0
    l0 = math.radians((280.46646 + t * (36000.76983 + t * 0.0003032)) % 360.0)
    m = math.radians(357.52911 + t * (35999.05029 - 0.0001537 * t))
    ecc = 0.016708634 - t * (0.000042037 + 0.0000001267 * t)
    c = (
        math.sin(m) * (1.914602 - t * (0.004817 + 0.000014 * t))
        + math.sin(2 * m) * (0.019993 - 0.000101 * t)
        + math.sin(3 * m) * 0.000289
    )
    omega = math.radians(125.04 - 1934.136 * t)
    lam = math.radians(math.degrees(l0) + c - 0.00569 - 0.00478 * math.sin(omega))
    eps = math.radians(
        23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0 + 0.00256 * math.cos(omega)
    )
    decl = math.asin(math.sin(eps) * math.sin(lam))
    y = math.tan(eps / 2.0) ** 2
    eot = 4.0 * math.degrees(
        y * math.sin(2 * l0)
        - 2 * ecc * math.sin(m)
        + 4 * ecc * y * math.sin(m) * math.cos(2 * l0)
        - 0.5 * y * y * math.sin(4 * l0)
        - 1.25 * ecc * ecc * math.sin(2 * m)
    )
    minutes = float((days + 0.5) % 1.0) * 1440.0
    hour_angle = math.radians((minutes + eot + 4.0 * lon) / 4.0 - 180.0)
    phi = math.radians(lat)
    sin_el = math.sin(phi) * math.sin(decl) + math.cos(phi) * math.cos(decl) * math.cos(hour_angle)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, sin_el))))
    azimuth = (
        math.degrees(
            math.atan2(math.sin(hour_angle), math.cos(hour_angle) * math.sin(phi) - math.tan(decl) * math.cos(phi))
        )
        + 180.0
    )
    return azimuth % 360.0, elevation
