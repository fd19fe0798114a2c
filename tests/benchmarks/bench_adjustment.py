"""Bundle adjustment, 5 000 - 80 000 tie points x 3 images: adjust vs scipy.optimize.least_squares.

The problem: a simulated 10 km SPOT 5 triplet (HRG, HRS1, HRS2; rigorous SpotModels), the truth
models given look-angle errors (psi_x_0, psi_y_0 of 10-20 microrad per image); 19 control points
(0.3 px, ground sigma 0.5 m) and N tie points on the true DSM measured in all three images with
0.3 px noise; free: look:1 (psi_x, psi_y of degree 0 and 1 per image, 12 unknowns). `adjust` is
timed end to end (start points by forward intersection, iterations, statistics). The peer,
scipy_bundle.ScipyBundle: the same observations, weights, unknowns (orientation + 3 per point) and
starting values, residuals from the models' ground_to_image, the analytic sparse Jacobian from
their `partials`, method="trf" with tr_solver="lsmr", timed from the start points to the solution
(no statistics). Both: best of REPEAT runs (one run for the largest N). Differences: orientation
unknowns over `adjust`'s sigmas and in microrad, points in metres."""

import os
import pathlib
import tempfile
import time

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.bundle import adjust
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.helpers.adjustment_scene import point_observations, synthetic_points
from tests.helpers.scipy_bundle import ScipyBundle

SIZES = (5000, 20000, 80000)
REPEAT = 3
IDS = {"HRG": 1, "HRS1": 2, "HRS2": 3}
LABELS = {i: name for name, i in IDS.items()}
#: look-angle errors given to the truth models (rad): psi_x_0, psi_y_0 per image
INJECTED = {1: (2.0e-5, -1.0e-5), 2: (-1.5e-5, 0.8e-5), 3: (1.0e-5, 1.2e-5)}
FREE = ["look:1"]
SIGMA_PX = 0.3
CONTROL = 19
#: scipy's ftol, xtol, gtol and lsmr's atol, btol: the loosest of 1e-8 ... 1e-13 whose solution agrees
#: with adjust's to 1e-6 sigma from the lines-of-sight start (1e-8: 2e-4; 1e-12: up to 1.8e-6 sigma,
#: scipy stopping on xtol short of the minimum; 1e-13: 1e-8 to 3e-8 sigma)
SCIPY_TOLERANCE = 1e-13


def supplied_models(paths):
    """The truth models with the INJECTED look-angle errors (a fresh set: adjust edits them)."""
    models = {i: sensors.load(paths["truth_metadata"][name]) for name, i in IDS.items()}
    for i, (dx, dy) in INJECTED.items():
        models[i].orientation.corrections.look[:, 0] = (dx, dy)
    return models


def problem(paths, n, control=CONTROL, seed=1):
    """Observations: the simulator's first `control` point candidates as control points (the rest
    check points, which adjust ignores) and n tie points seen inside all three images."""
    draw = synthetic_points(paths, IDS, int(1.1 * n) + 20, SIGMA_PX, seed)
    m = draw.measurements
    sizes = {i: sensors.load(paths["truth_metadata"][name]).size for name, i in IDS.items()}
    size = np.array([sizes[i] for i in m["image_id"]])
    outside = (m["col"] < 0) | (m["col"] > size[:, 0]) | (m["row"] < 0) | (m["row"] > size[:, 1])
    inside = np.bincount(m["point"][outside], minlength=len(draw.points)) == 0
    ties = draw.subset(inside & (np.cumsum(inside) <= n))
    if len(ties.points) < n:
        raise RuntimeError(f"only {len(ties.points)} of {n} tie points inside all images")
    ties.points["role"] = "tie"
    for key in ("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h"):
        ties.points[key] = np.nan
    ties.points["name"] = [f"T{k}" for k in range(n)]
    return point_observations(paths["points"], IDS, control, SIGMA_PX).concatenate(ties)


def time_adjust(paths, obs, height, repeat):
    """(best wall time of `repeat` runs, the last Adjustment)."""
    best = np.inf
    for _ in range(repeat):
        models = supplied_models(paths)
        start = time.perf_counter()
        result = adjust(models, obs, FREE, names=LABELS, height=height)
        best = min(best, time.perf_counter() - start)
    return best, result


def time_scipy(paths, obs, height, repeat):
    """(best wall time of `repeat` runs, orientation unknowns, lon, lat, h, OptimizeResult) of ScipyBundle."""
    best = np.inf
    for _ in range(repeat):
        models = supplied_models(paths)
        start = time.perf_counter()
        x, lon, lat, h, result = ScipyBundle(models, obs, FREE, names=LABELS, height=height).solve(SCIPY_TOLERANCE)
        best = min(best, time.perf_counter() - start)
    return best, x, lon, lat, h, result


def differences(ours, x, lon, lat, h):
    """Largest |scipy - adjust| of the orientation unknowns (over adjust's sigmas; microrad) and of
    the points (m, east/north/up)."""
    free = ours.parameters.free
    d = x - ours.values[free]
    east, north = metres_per_degree(ours.lat, ours.h)
    points = np.column_stack([(lon - ours.lon) * east, (lat - ours.lat) * north, h - ours.h])
    return float(np.max(np.abs(d) / ours.sigmas[free])), float(np.max(np.abs(d)) * 1e6), float(np.max(np.abs(points)))


def run():
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        paths = simulate_scene(SceneConfig.small(size_km=10.0, points=30, error_scale=0.0), pathlib.Path(folder) / "s")
        warm_up = problem(paths, 200)
        height = float(np.nanmean(warm_up.points["h"]))  # of the control points: the tie points' start
        adjust(supplied_models(paths), warm_up, FREE, names=LABELS, height=height)  # numba cache load
        for n in SIZES:
            obs = problem(paths, n)
            repeat = REPEAT if n < max(SIZES) else 1
            seconds, ours = time_adjust(paths, obs, height, repeat)
            peer, x, lon, lat, h, result = time_scipy(paths, obs, height, repeat)
            rel, urad, metres = differences(ours, x, lon, lat, h)
            rows.append(
                {
                    "tie points": n,
                    "measurements": len(ours.observations.measurements),
                    "iterations": ours.iterations,
                    "sigma_0": ours.sigma0,
                    "adjust s": seconds,
                    "s per 1000 points": 1000.0 * seconds / n,
                    "scipy s": peer,
                    "scipy / adjust": peer / seconds,
                    "scipy f, J evaluations": f"{result.nfev}, {result.njev}",
                    "max d orientation / sigma": rel,
                    "max d orientation urad": urad,
                    "max d point m": metres,
                    "load average": os.getloadavg()[0],
                }
            )
            print(rows[-1], flush=True)
    return rows


if __name__ == "__main__":
    run()
