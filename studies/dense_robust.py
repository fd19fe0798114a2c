"""Does LSM's robust weighting, and leaving isolated refinements at their dense positions, give the dense DSM
better heights? On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the DSM's height range +- 100 m), dense
matching (algorithms/dense, default DenseParams without the wide second window, studies/sim_dense.py) with plain
or robust LSM (DenseParams.robust) and with or without the isolation test (refine.isolated; off:
refine.LEAST_REFINED = 0), every point intersected with the TRUE models (the matching's error alone), and the
dense pipeline model's 10 m DSM (dem_tiles method "cells": refined points only, RADIUS 1, gaps filled within 10
cells) against the true DSM at the evaluation cells of tests/helpers/dsm_comparison.py, RMS by class (region
growing's and CARS's are in docs/validation.md#dense-peers). Also the share of the points refined in all their
positions, by class."""

import tempfile
import time

import numpy as np

from pushbroom.algorithms.dense import refine
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from studies.sim_dense import BEFORE, model_dem, truth_cloud
from tests.helpers.dsm_comparison import Truth

ZONES = ("bare", "crops", "open near forest/city/water", "forest", "city")


def dsm_errors(paths, truth, robust, isolation, folder):
    """(dh at the evaluation cells, share of the points refined) of one variant."""
    least = refine.LEAST_REFINED
    refine.LEAST_REFINED = least if isolation else 0
    try:
        # without the wide second window (dense_wide), which came after these figures
        cloud = truth_cloud(paths, truth, DenseParams(robust=robust, wide_template=0, **BEFORE))
    finally:
        refine.LEAST_REFINED = least
    dh, _ = model_dem(cloud, truth, folder)
    return dh, float(np.isfinite(cloud.points.points["rho_min"]).mean())


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
