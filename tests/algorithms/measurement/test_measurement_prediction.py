"""Predicted image positions and ground points of clicks (measurement/prediction.py), against the
simulator's truth: with the TRUE sensor models the points.csv ground points land on their true image
positions, and a click on a true image position comes back to the point's ground coordinates on the
true DSM (first ray/DSM intersection) or at its height."""

import csv

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.measurement.prediction import ground_from_click, predict

NAMES = ("HRG", "HRS1", "HRS2")


@pytest.fixture(scope="module")
def truth(small_scene):
    models = {n: sensors.load(small_scene["truth_metadata"][n]) for n in NAMES}
    with open(small_scene["points"], newline="") as f:
        return models, list(csv.DictReader(f)), read_dem(small_scene["dsm"])


def test_predict_lands_on_the_true_positions(truth, figures):
    models, rows, _ = truth
    worst = 0.0
    for r in rows:
        got = predict(models, float(r["lon"]), float(r["lat"]), float(r["h"]))
        assert sorted(got) == sorted(NAMES)
        for n, (col, row) in got.items():
            worst = max(worst, abs(col - float(r[f"{n}_col"])), abs(row - float(r[f"{n}_row"])))
    figures.report("largest difference to the simulator's true positions", worst, "px")
    assert worst < 1e-2
    r = rows[0]
    outside = predict(models, float(r["lon"]) + 0.2, float(r["lat"]), float(r["h"]))
    assert outside == {n: None for n in NAMES}


def test_ground_from_click_on_the_dsm_and_at_a_height(truth, figures):
    models, rows, dsm = truth
    worst = np.zeros(3)
    for r in rows:
        lon, lat, h = float(r["lon"]), float(r["lat"]), float(r["h"])
        e_deg, n_deg = metres_per_degree(lat, h)
        for n in NAMES:
            col, row = float(r[f"{n}_col"]), float(r[f"{n}_row"])
            for dem, height in ((dsm, 0.0), (None, h)):
                got = ground_from_click(models[n], col, row, dem=dem, height=height)
                d = np.abs([(got[0] - lon) * e_deg, (got[1] - lat) * n_deg, got[2] - h])
                worst = np.maximum(worst, d)
            assert ground_from_click(models[n], col, row, height=h)[2] == h
    figures.report("largest ground differences E, N, H", worst, "m")
    assert (worst < 0.05).all()


def test_ground_from_click_without_a_ground_point(truth):
    models, rows, dsm = truth
    elsewhere = Dem.constant(300.0, (10.0, 10.0, 10.1, 10.1))
    with pytest.raises(InputError, match="no ground point for image position"):
        ground_from_click(models["HRG"], 100.0, 100.0, dem=elsewhere)
