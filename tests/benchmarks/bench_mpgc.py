"""MPGC throughput (algorithms/matching/mpgc.py): HRG -> HRS1 + HRS2 of the simulated 3 km SPOT 5
triplet with the truth models, HRG template centres on a 10 px lattice, approximations 10-20 m off
along the HRG ray; points/s with 1 and 2 threads (numba.set_num_threads), against pairwise LSM into
both HRS images from the same approximations. Best of three after JIT warm-up."""

import tempfile

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching import lsm, mpgc
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.params import GrowParams, LsmParams
from pushbroom.algorithms.matching.resolution import adapt_resolution
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.benchmarks.benchutil import best_time, thread_counts

NAMES = ("HRG", "HRS1", "HRS2")


def run():
    with tempfile.TemporaryDirectory() as tmp:
        paths = simulate_scene(SceneConfig.small(), tmp + "/scene")
        models = [sensors.load(paths["truth_metadata"][name]) for name in NAMES]
        dsm = read_dem(paths["dsm"])
        lo, hi = dsm.height_range
        cols, rows = models[0].size
        x0, y0 = (v.ravel() for v in np.meshgrid(np.arange(25.5, cols - 25, 10.0), np.arange(25.5, rows - 25, 10.0)))
        lon, lat, h = models[0].image_to_dem(x0, y0, dsm)
        rng = np.random.default_rng(5)
        h = h + rng.choice([-1, 1], x0.size) * rng.uniform(10.0, 20.0, x0.size)
        lon, lat = models[0].image_to_ground(x0, y0, h)
        cen, jac = mpgc.geometry(models, lon, lat, h)
        inside = np.all(
            [
                (cen[:, i, 0] > 30)
                & (cen[:, i, 0] < m.size[0] - 30)
                & (cen[:, i, 1] > 30)
                & (cen[:, i, 1] < m.size[1] - 30)
                for i, m in enumerate(models)
            ],
            axis=0,
        )
        x0, y0, lon, lat, h = (v[inside] for v in (x0, y0, lon, lat, h))
        start = mpgc.initial_state(*mpgc.geometry(models, lon, lat, h))
        images = [Image(paths["images"][name]["imagery"]) for name in NAMES]
        ref, _ = adapt_resolution(images[0], images[1], models[0], models[1], GrowParams(), (lo - 100, hi + 100))
        images[0] = ref
        arrays = [im.read(0, 0, *im.size)[0] for im in images]
        params = mpgc.MpgcParams(sigma_geometry=0.05)

        def multi():
            return mpgc.match_points(images[0], images[1:], models, x0, y0, (lon, lat, h), params)

        def pairwise():
            return [
                lsm.match_points(
                    arrays[0],
                    arrays[i + 1],
                    x0,
                    y0,
                    start[:, i, 0],
                    start[:, i, 3],
                    affine=start[:, i, [1, 2, 4, 5]],
                    params=LsmParams(),
                )
                for i in range(2)
            ]

        rows = []
        for threads in thread_counts():
            for name, call in (("mpgc 3 images", multi), ("pairwise lsm x 2", pairwise)):
                seconds = best_time(call)
                rows.append(
                    {
                        "operation": name,
                        "threads": threads,
                        "points": int(x0.size),
                        "seconds": seconds,
                        "points/s": x0.size / seconds,
                        "points/s/core": x0.size / seconds / threads,
                    }
                )
        images.clear()
        del ref
        return rows
