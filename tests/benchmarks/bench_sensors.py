"""Rigorous SPOT model throughput: image_to_ground, ground_to_image, image_to_dem, partials.

Runs on the real SPOT 5 scene (benchutil.SHARED_DATA) when present, else on a synthetic 12000-detector
scene; times are the best of three after JIT warm-up."""

import os
import pathlib

import numpy as np

from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.sensors.spot import SpotModel
from tests.benchmarks.benchutil import SHARED_DATA, best_time

HERE = pathlib.Path(__file__).resolve().parent
SPOT5 = SHARED_DATA / "spot5_hrg1_2005" / "METADATA.DIM"


def scene_model():
    """(model, label): the real SPOT 5 scene, or a synthetic one of the same size."""
    if SPOT5.exists():
        return SpotModel.from_dimap(SPOT5), "SPOT 5 HRG (real metadata)"
    from tests.helpers.spot_synthetic import synthetic_orientation

    return SpotModel(synthetic_orientation(ncols=12000, nrows=12000)), "synthetic 12000 x 12000"


def terrain(model):
    """A 0-2000 m sinusoidal DEM (about 30 m cells) over the scene footprint."""
    ring = model.footprint(h=0.0)
    west, south = ring.min(axis=0) - 0.05
    east, north = ring.max(axis=0) + 0.05
    lon = np.linspace(west, east, 2000)
    lat = np.linspace(north, south, 2000)
    x, y = np.meshgrid(lon, lat)
    heights = 1000 + 1000 * np.sin(np.radians(x) * 3000) * np.cos(np.radians(y) * 2000)
    step_lon, step_lat = lon[1] - lon[0], lat[1] - lat[0]
    return Dem(heights, (west - step_lon / 2, step_lon, 0.0, north - step_lat / 2, 0.0, step_lat))


def run():
    model, label = scene_model()
    cols, rows = model.size
    line_c = np.arange(cols) + 0.5
    line_r = np.full(cols, rows / 2)
    grid_c, grid_r = (v.ravel() for v in np.meshgrid(np.linspace(0, cols, 1000), np.linspace(0, rows, 1000)))
    line_h, grid_h = np.full(line_c.size, 500.0), np.full(grid_c.size, 500.0)
    line_ground = model.image_to_ground(line_c, line_r, line_h)
    grid_ground = model.image_to_ground(grid_c, grid_r, grid_h)
    dem = terrain(model)
    cases = [
        (
            "image_to_ground",
            f"one line ({cols} detectors)",
            line_c.size,
            lambda: model.image_to_ground(line_c, line_r, line_h),
        ),
        ("image_to_ground", "1000 x 1000 grid", grid_c.size, lambda: model.image_to_ground(grid_c, grid_r, grid_h)),
        (
            "ground_to_image",
            f"one line ({cols} points)",
            line_c.size,
            lambda: model.ground_to_image(*line_ground, line_h),
        ),
        ("ground_to_image", "1000 x 1000 grid", grid_c.size, lambda: model.ground_to_image(*grid_ground, grid_h)),
        (
            "image_to_dem",
            "1000 x 1000 grid, 2000 x 2000 DEM",
            grid_c.size,
            lambda: model.image_to_dem(grid_c, grid_r, dem),
        ),
        (
            "partials",
            "10000 points (32 coefficients + ground)",
            10000,
            lambda: model.partials(grid_ground[0][:10000], grid_ground[1][:10000], grid_h[:10000]),
        ),
    ]
    rows_out = []
    for operation, data, n, function in cases:
        seconds = best_time(function)
        rows_out.append(
            {
                "operation": operation,
                "data": data,
                "points": n,
                "seconds": seconds,
                "points/s": n / seconds,
                "scene": label,
                "cores": os.cpu_count(),
            }
        )
    return rows_out


if __name__ == "__main__":
    results = run()
    print(f"{'operation':<16} {'data':<42} {'points':>9} {'seconds':>9} {'points/s':>12}")
    for r in results:
        print(f"{r['operation']:<16} {r['data']:<42} {r['points']:>9} {r['seconds']:>9.4f} {r['points/s']:>12.4g}")
    print(f"({results[0]['scene']}, {results[0]['cores']} cores)")
