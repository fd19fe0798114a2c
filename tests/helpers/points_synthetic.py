"""Synthetic multi-image points (MultiPoints) and a flat stand-in sensor model, shared by the point
storage tests and benchmarks/bench_points.py."""

import numpy as np

from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints


def synthetic(n, seed=0, images=(1, 2, 3)):
    """n points on images `images`; groups cycle 1, 2, 3; group 1 points miss the last image."""
    rng = np.random.default_rng(seed)
    p = np.zeros(n, POINT_DTYPE)
    p["id"] = np.arange(1, n + 1)
    p["group"] = np.arange(n) % 3 + 1
    p["flags"] = np.array([1, 3, 7])[p["group"] - 1]
    p["rho_min"] = rng.uniform(0.6, 1.0, n)
    p["rho_a"], p["rho_b"], p["rho_c"], p["dx"], p["dy"] = p["rho_min"], np.nan, np.nan, np.nan, np.nan
    obs = np.zeros(3 * n, OBS_DTYPE)
    obs["point_id"] = np.repeat(p["id"], 3)
    obs["image_id"] = np.tile(images, n)
    obs["col"], obs["row"] = rng.uniform(0, 1000, 3 * n), rng.uniform(0, 1000, 3 * n)
    obs["rho"] = rng.uniform(0.6, 1.0, 3 * n)
    keep = ~((np.repeat(p["group"], 3) == 1) & (obs["image_id"] == images[-1]))
    return MultiPoints(p, obs[keep], {"images": list(images), "matched_3": int(n // 3)})


class FlatModel:
    """lon/lat linear in col/row (a stand-in for a sensor model)."""

    size = (1000, 1000)

    def image_to_ground(self, col, row, h):
        return -84.2 + np.asarray(col) * 1e-5, 36.6 - np.asarray(row) * 1e-5


def two_ray_points(n, rng=None):
    """n group-1 points, each measured on images 1 and 2: all at (500, 500) px, or, with a numpy
    Generator `rng`, spread uniformly over 1000 x 1000 px."""
    p = np.zeros(n, POINT_DTYPE)
    p["id"], p["group"] = np.arange(n), 1
    o = np.zeros(2 * n, OBS_DTYPE)
    o["point_id"], o["image_id"] = np.repeat(p["id"], 2), np.tile([1, 2], n)
    o["col"], o["row"] = (500.0, 500.0) if rng is None else rng.uniform(0, 1000, (2, 2 * n))
    return MultiPoints(p, o)
