"""Does LSM's robust weighting, and leaving isolated refinements at their dense positions, give the dense DSM
better heights? On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the DSM's height range +- 100 m), dense
matching (algorithms/dense, default DenseParams) with plain or robust LSM (DenseParams.robust) and with or
without the isolation test (refine.isolated; off: refine.LEAST_REFINED = 0), every point intersected with the
TRUE models (the matching's error alone), and the dense pipeline model's 10 m DSM (dem_tiles method "cells":
refined points only, RADIUS 1, gaps filled within 10 cells) against the true DSM at the evaluation cells of
tests/helpers/dsm_comparison.py, RMS by class (region growing's and CARS's are in docs/validation.md#dense-peers).
Also the share of the points refined in all their positions, by class."""

import tempfile
import time

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense import refine
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
from pushbroom.algorithms.surface.pointcloud import write_las
from pushbroom.algorithms.surface.tin_dem import DemParams
from scripts.bench_peers import sample
from tests.helpers.dsm_comparison import CELL, NAMES, Truth

ZONES = ("bare", "crops", "open near forest/city/water", "forest", "city")


def dsm_errors(paths, truth, robust, isolation, folder):
    """(dh at the evaluation cells, share of the points refined) of one variant."""
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    lo, hi = read_dem(paths["dsm"]).height_range
    least = refine.LEAST_REFINED
    refine.LEAST_REFINED = least if isolation else 0
    try:
        parts, _ = match_dense_tiles(
            images,
            models,
            f"{folder}/dense",
            params=DenseParams(robust=robust),
            height_range=(lo - 100.0, hi + 100.0),
            execution=Execution("threads", 2),
        )
    finally:
        refine.LEAST_REFINED = least
    pts = np.concatenate([p.points for p in parts])
    obs = np.concatenate([p.observations for p in parts])
    res = intersection.intersect(
        truth.models,
        intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]),
        h0=0.5 * (lo + hi),
    )
    ok = res.ok
    rho = pts["rho_min"][np.searchsorted(pts["id"], res.point[ok])].astype(np.float32)
    x, y = reproject(res.lon[ok], res.lat[ok], wgs84(), truth.srs)
    write_las(f"{folder}/dense.las", x, y, res.h[ok], {"rho": rho, "rays": res.rays[ok].astype(np.uint8)}, truth.srs)
    dem_from_point_cloud(
        f"{folder}/dense.las",
        f"{folder}/dem.tif",
        DemParams(cell=CELL, method="cells", fallback=False, fill=10.0, radius=1),
    )
    return sample(f"{folder}/dem.tif", truth) - truth.h, float(np.isfinite(pts["rho_min"]).mean())


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    print("| LSM | isolated refinements | refined points | " + " | ".join(ZONES) + " | non-water cells |")
    print("|---" * (len(ZONES) + 4) + "|")
    for robust, isolation in ((False, False), (True, False), (False, True), (True, True)):
        t = time.perf_counter()
        dh, refined = dsm_errors(paths, truth, robust, isolation, tempfile.mkdtemp())
        table = truth.table(dh, np.isfinite(dh))
        print(
            f"| {'robust' if robust else 'plain'} | {'dense position' if isolation else 'kept'} | "
            f"{100 * refined:.1f} % | "
            + " | ".join(f"{table[z][2]:.2f} m" for z in ZONES)
            + f" | {100 * np.isfinite(dh[~truth.water]).mean():.1f} % | ({time.perf_counter() - t:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
