"""Acquisition planning: the orbit of each pass and each image's timing, pointing and size, such
that every image is centred on the scene centre.

Per pass, the orbit is solved so that the reference image's centre detector (mirror viewing
angle `roll`) sees the scene centre at 10:45 local mean solar time (SPOT's descending node is at
10:30); the other images of the pass get the time and across-track angle (psi_y) at which their
centre detector sees it (SPOT 5 HRS1/HRS2 about 45 s before/after the HRG)."""

import dataclasses
import math

import numpy as np

from ..geodesy import ecef_to_geodetic, geodetic_to_ecef
from .instruments import LookAngles, instruments, table_residuals
from .orbit import Attitude, orbit_through, time_and_roll
from .truth import ImageTruth

LOCAL_TIME_HOURS = 10.75
SPOT5_CURVATURE = 2e-6  # rad, psi_x smile at the ends of a SPOT 5 array (no table given)


def plan(configuration, centre, size_m, dates, roll_deg, rng, look_table=None):
    """ImageTruth of every image of `configuration` over `centre` = (lon, lat, h), `size_m`
    wide and long. `look_table`: optional (psi_x, psi_y, line_period) of a real scene."""
    target = geodetic_to_ecef(*centre)
    table = table_residuals(*look_table[:2]) if look_table else None
    images = []
    for pass_index, date in enumerate(dates):
        t_c = ((LOCAL_TIME_HOURS - centre[0] / 15.0) % 24.0) * 3600.0
        attitude = Attitude.random(rng, t_c)
        roll = math.radians(roll_deg[pass_index])
        orbit = None
        members = [s for s in instruments(configuration) if s.pass_index == pass_index]
        for spec in sorted(members, key=lambda s: not s.reference):
            if look_table:
                spec = dataclasses.replace(spec, line_period=look_table[2])
            ncols = max(2, int(round(size_m / spec.gsd)))
            curvature = SPOT5_CURVATURE if spec.mission == 5 and table is None else 0.0
            look = LookAngles(spec.psi_x, 0.0, spec.ifov, ncols, table, curvature)
            psi_x, psi_y0 = look(0.5 * ncols)
            if orbit is None:
                orbit = orbit_through(target, t_c, attitude, psi_x, roll)
                t_mid, psi_y = t_c, roll
            else:
                guess = t_c - 48.0 * math.tan(spec.psi_x) / math.tan(math.radians(20.0))
                t_mid, psi_y = time_and_roll(orbit, attitude, target, psi_x, guess)
            pos, vel = orbit.state(t_mid)
            ground_speed = np.linalg.norm(vel) * np.linalg.norm(target) / np.linalg.norm(pos)
            nrows = max(2, int(round(size_m / (ground_speed * spec.line_period))))
            centre_row = nrows // 2 + 0.5
            images.append(
                ImageTruth(
                    spec,
                    orbit,
                    attitude,
                    look.with_centre(psi_y - psi_y0),
                    ncols,
                    nrows,
                    t_mid + (centre_row - 0.5 * nrows) * spec.line_period,
                    centre_row,
                    np.datetime64(date, "ns"),
                )
            )
    return images


def ray_at_height(pos, direction, h, iterations=6):
    """(lon, lat) where rays pos + mu direction (n, 3) reach ellipsoidal height h:
    Newton on mu with dh/dmu = -|d . up| approximated by the local vertical component."""
    pos = np.atleast_2d(pos)
    d = direction / np.linalg.norm(direction, axis=1, keepdims=True)
    lon, lat, hp = ecef_to_geodetic(pos)
    mu = (hp - h) / np.abs(np.sum(d * pos / np.linalg.norm(pos, axis=1, keepdims=True), axis=1))
    for _ in range(iterations):
        lon, lat, hh = ecef_to_geodetic(pos + mu[:, None] * d)
        up = geodetic_to_ecef(lon, lat, np.ones_like(lon)) - geodetic_to_ecef(lon, lat, np.zeros_like(lon))
        mu = mu + (hh - h) / np.abs(np.sum(d * up, axis=1))
    return lon, lat


def footprint_bounds(images, heights, per_side=8):
    """(lon_min, lat_min, lon_max, lat_max) of all images' border rays at the given heights."""
    lons, lats = [], []
    t = np.linspace(0.0, 1.0, per_side + 1)
    for image in images:
        cols = np.concatenate([t * image.ncols, np.full(t.size, image.ncols), t * image.ncols, np.zeros(t.size)])
        rows = np.concatenate([np.zeros(t.size), t * image.nrows, np.full(t.size, image.nrows), t * image.nrows])
        pos, mat = image.line_geometry(rows)
        direction = np.einsum("nij,nj->ni", mat.reshape(-1, 3, 3), image.look_vectors(cols))
        for h in heights:
            lon, lat = ray_at_height(pos, direction, h)
            lons.append(lon)
            lats.append(lat)
    lons, lats = np.concatenate(lons), np.concatenate(lats)
    return float(lons.min()), float(lats.min()), float(lons.max()), float(lats.max())
