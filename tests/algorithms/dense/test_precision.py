"""The dense points' image sigmas and surface term (dense/precision.py), against the formulas written out."""

import numpy as np
import pytest

from pushbroom.algorithms.dense.precision import RPC, SPOT, calibration_of, image_sigmas, with_spread
from pushbroom.algorithms.matching.points import DENSE, OBS_DTYPE, POINT_DTYPE, REFINED


def table(rows, dtype):
    out = np.zeros(len(rows), dtype)
    for k, row in enumerate(rows):
        for name, value in row.items():
            out[k][name] = value
    return out


def test_sigmas_of_refined_dense_points_and_the_default_elsewhere():
    nan = np.nan
    points = table(
        [
            {"id": 1, "flags": DENSE, "rho_min": 0.9},  # refined, three rays
            {"id": 2, "flags": DENSE, "rho_min": 0.8},  # refined, two rays
            {"id": 3, "flags": DENSE, "rho_min": nan},  # a semi-global position left
            {"id": 4, "flags": REFINED, "rho_min": 0.9},
        ],
        POINT_DTYPE,
    )  # region growing
    obs = table(
        [
            {"point_id": 1, "image_id": 1, "rho": nan},
            {"point_id": 1, "image_id": 2, "rho": 0.9, "semi_major": 0.06},
            {"point_id": 1, "image_id": 3, "rho": 0.95, "semi_major": 0.04},
            {"point_id": 2, "image_id": 1, "rho": nan},
            {"point_id": 2, "image_id": 2, "rho": 0.8, "semi_major": 0.1},
            {"point_id": 3, "image_id": 1, "rho": nan},
            {"point_id": 3, "image_id": 2, "rho": 0.9, "semi_major": 0.05},
            {"point_id": 3, "image_id": 3, "rho": nan, "semi_major": nan},
            {"point_id": 4, "image_id": 1, "rho": nan},
            {"point_id": 4, "image_id": 2, "rho": 0.9, "semi_major": 0.05},
        ],
        OBS_DTYPE,
    )
    got = image_sigmas(points, obs, 0.5, SPOT.factors)
    f2, f3, r2 = SPOT.factors[2], SPOT.factors[3], np.sqrt(2.0)
    want = [
        f3 * 0.04 / r2,
        f3 * 0.06 / r2,
        f3 * 0.04 / r2,  # the reference: the smaller of its pairs
        f2 * 0.1 / r2,
        f2 * 0.1 / r2,
        0.5,
        0.5,
        0.5,
        0.5,
        0.5,
    ]
    assert got == pytest.approx(want, rel=1e-6)
    assert image_sigmas(points, obs, 0.5, {2: 1.0, 3: 1.0})[1] == pytest.approx(0.06 / r2, rel=1e-6)


def test_the_surface_term_adds_in_quadrature():
    got = with_spread(np.array([0.3, 0.3, 0.4]), np.array([0.8, np.nan, 0.0]), 0.5)
    assert got == pytest.approx([np.hypot(0.3, 0.5 * 0.8), 0.3, 0.4])


def test_the_calibration_is_the_sensors(pleiades_triplet, spot5_dim):
    """RPC factors where every model of the block is an RPC model (Pleiades), SPOT's where one is a rigorous SPOT
    model; the RPC factors are smaller (the real Pleiades images' LSM ellipses are near true, the simulated SPOT
    images' optimistic: studies/README.md#pair_precision)."""
    from pushbroom.algorithms import sensors

    rpc = [sensors.load(p) for p in pleiades_triplet[:2]]
    spot = sensors.load(spot5_dim)
    assert calibration_of(rpc) is RPC and calibration_of(rpc + [spot]) is SPOT and calibration_of([spot]) is SPOT
    assert RPC.factors[2] < SPOT.factors[2] and RPC.factors[3] < SPOT.factors[3] and RPC.spread < SPOT.spread
