"""Shared fixture data for the adjustment tests: a simulated SPOT scene with its control/check
point candidates as Observations, the supplied and the truth models, and synthetic check points."""

import csv

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.bundle import check_points
from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.stats import statistics_table


def point_observations(csv_path, image_ids, n_control, sigma_px=0.3, sigma_ground=(0.5, 0.5, 0.5)):
    """Observations of the simulator's points.csv: the first n_control points control, the rest
    check; measured image coordinates (the "_meas" columns)."""
    rows = list(csv.DictReader(open(csv_path)))
    points = np.zeros(len(rows), POINT_DTYPE)
    meas = []
    for k, r in enumerate(rows):
        points[k] = (
            r["id"],
            "control" if k < n_control else "check",
            float(r["lon"]),
            float(r["lat"]),
            float(r["h"]),
            *sigma_ground,
        )
        for name, i in image_ids.items():
            if r.get(f"{name}_col_meas"):
                meas.append((k, i, float(r[f"{name}_col_meas"]), float(r[f"{name}_row_meas"]), sigma_px))
    return Observations(points, np.array(meas, MEAS_DTYPE))


def scene_models(paths, names, truth=False):
    """{block image id: sensor model} of the simulated scene `paths` (simulate_scene) images `names`, ids
    1, 2, ... in that order; with `truth`, the models the images were simulated with."""
    key = "truth_metadata" if truth else None
    return {
        k + 1: sensors.load(paths[key][n] if truth else paths["images"][n]["metadata"]) for k, n in enumerate(names)
    }


def synthetic_points(scene, image_ids, n, sigma_px, seed):
    """Check points: n ground points on the true DSM, spread over the first image of `image_ids`
    ({name: image id}), measured in each (truth models) with image noise sigma_px."""
    rng = np.random.default_rng(seed)
    truth = {i: sensors.load(scene["truth_metadata"][name]) for name, i in image_ids.items()}
    first = truth[next(iter(image_ids.values()))]
    cols, rows = first.size
    x, y = rng.uniform(30, cols - 30, n), rng.uniform(30, rows - 30, n)
    lon, lat, h = first.image_to_dem(x, y, read_dem(scene["dsm"]))
    meas = []
    for i, model in truth.items():
        c, r = model.ground_to_image(lon, lat, h)
        c, r = c + rng.normal(0, sigma_px, n), r + rng.normal(0, sigma_px, n)
        meas += [(k, i, c[k], r[k], sigma_px) for k in range(n)]
    points = np.zeros(n, POINT_DTYPE)
    points["name"] = [f"S{k}" for k in range(n)]
    points["role"], points["lon"], points["lat"], points["h"] = "check", lon, lat, h
    return Observations(points, np.array(meas, MEAS_DTYPE))


def check_rms(result, observations, height, figures, label="check points"):
    """(RMS of dE, dN, dH, RMS of their theoretical sigmas) of the check points of `observations`
    intersected with the adjusted models (bundle.check_points), reported to `figures` as `label`."""
    check = check_points(result, observations, height=height)
    table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")})
    rms = np.array([table[k][4] for k in ("dE", "dN", "dH")])
    theoretical = np.sqrt(np.mean(check["sigma"] ** 2, axis=0))
    figures.table(
        f"{label} (m)",
        [{"": key, "RMS": rms[k], "theoretical": theoretical[k]} for k, key in enumerate(("dE", "dN", "dH"))],
    )
    return rms, theoretical


#: the triplet's image names, ids and labels in the adjustment tests' scene
NAMES = ("HRG", "HRS1", "HRS2")
IDS = {n: k + 1 for k, n in enumerate(NAMES)}
LABELS = {k + 1: n for k, n in enumerate(NAMES)}
#: look-angle errors injected into the supplied models (rad): psi_x_0, psi_y_0 per image
INJECTED = {1: (2.0e-5, -1.0e-5), 2: (-1.5e-5, 0.8e-5), 3: (1.0e-5, 1.2e-5)}


def perturbed(scene):
    """The scene's supplied models {id: model} with the INJECTED look-angle errors."""
    models = scene_models(scene, NAMES)
    for i, (dx, dy) in INJECTED.items():
        models[i].orientation.corrections.look[:, 0] = (dx, dy)
    return models
