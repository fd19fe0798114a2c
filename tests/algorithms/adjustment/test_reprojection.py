"""Per-image reprojection statistics (algorithms/adjustment/reprojection.py) on residuals whose
means and RMS are known by construction, and against a per-measurement loop on random ones."""

from types import SimpleNamespace

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.adjustment.reprojection import ALL, reprojection_rms
from pushbroom.algorithms.errors import InputError


def result_of(roles, meas, residuals):
    """An Adjustment-like object: points of `roles`, measurements (point, image id), residuals (M, 2)."""
    points = np.zeros(len(roles), POINT_DTYPE)
    points["name"] = [f"P{k}" for k in range(len(roles))]
    points["role"] = roles
    m = np.zeros(len(meas), MEAS_DTYPE)
    m["point"], m["image_id"] = np.array(meas).T
    return SimpleNamespace(observations=Observations(points, m), residuals=np.asarray(residuals, float))


def test_shift_and_symmetric_residuals():
    # image 3: a pure shift (3, 4) px; image 1: +-1 px in col; the control point's measurement (9 px) is not a tie
    r = result_of(
        ["tie", "tie", "control"], [(0, 3), (0, 1), (1, 3), (1, 1), (2, 1)], [(3, 4), (1, 0), (3, 4), (-1, 0), (9, 9)]
    )
    rows = reprojection_rms(r)
    assert rows["image_id"].tolist() == [1, 3, ALL] and rows["n"].tolist() == [2, 2, 4]
    one, three, total = rows
    assert (three["mean_col"], three["mean_row"], three["rms"]) == (3.0, 4.0, 5.0)
    assert (one["mean_col"], one["rms_col"], one["rms_row"], one["rms"]) == (0.0, 1.0, 0.0, 1.0)
    assert total["rms"] == pytest.approx(np.sqrt((25 + 25 + 1 + 1) / 4))
    with_control = reprojection_rms(r, roles=("tie", "control"))
    assert with_control["n"].tolist() == [3, 2, 5] and with_control[0]["mean_col"] == pytest.approx(3.0)
    assert reprojection_rms(r, roles=("check",))["n"].tolist() == [0]


def test_random_residuals_against_a_loop():
    rng = np.random.default_rng(1)
    meas = [(p, i) for p in range(40) for i in (2, 5, 7) if rng.random() < 0.8]
    v = rng.normal(0.3, 0.5, (len(meas), 2))
    rows = reprojection_rms(result_of(["tie"] * 40, meas, v))
    for row in rows:
        sel = [k for k, (_, i) in enumerate(meas) if row["image_id"] in (i, ALL)]
        squares = [v[k, 0] ** 2 + v[k, 1] ** 2 for k in sel]
        assert row["n"] == len(sel)
        assert row["rms"] == pytest.approx(np.sqrt(sum(squares) / len(sel)))
        assert row["mean_row"] == pytest.approx(sum(v[k, 1] for k in sel) / len(sel))
        assert row["rms_col"] == pytest.approx(np.sqrt(sum(v[k, 0] ** 2 for k in sel) / len(sel)))


def test_unknown_role_is_named():
    with pytest.raises(InputError, match="unknown point role.*'ties'"):
        reprojection_rms(result_of(["tie"], [(0, 1)], [(0, 0)]), roles=("ties",))
