"""Shared fixture data for the adjustment tests: a simulated SPOT scene with its control/check
point candidates as Observations, the supplied and the truth models, and matched tie points."""
import csv

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations


def point_observations(csv_path, image_ids, n_control, sigma_px=0.3, sigma_ground=(0.5, 0.5, 0.5)):
    """Observations of the simulator's points.csv: the first n_control points control, the rest
    check; measured image coordinates (the "_meas" columns)."""
    rows = list(csv.DictReader(open(csv_path)))
    points = np.zeros(len(rows), POINT_DTYPE)
    meas = []
    for k, r in enumerate(rows):
        points[k] = (r["id"], "control" if k < n_control else "check", float(r["lon"]), float(r["lat"]),
                     float(r["h"]), *sigma_ground)
        for name, i in image_ids.items():
            if r.get(f"{name}_col_meas"):
                meas.append((k, i, float(r[f"{name}_col_meas"]), float(r[f"{name}_row_meas"]), sigma_px))
    return Observations(points, np.array(meas, MEAS_DTYPE))


def models_of(paths, names, truth=False):
    key = "truth_metadata" if truth else None
    return {k + 1: sensors.load(paths[key][n] if truth else paths["images"][n]["metadata"])
            for k, n in enumerate(names)}
