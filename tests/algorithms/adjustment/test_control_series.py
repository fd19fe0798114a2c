"""Control point series (adjustment/control_series.py, Heipke et al. 1992, Table 1): the farthest-point choice on a
regular grid, each row against a direct adjustment with the same control points, fixed check
points, untouched input models, progress, cancelling and refusals; on the small SPOT 5 triplet."""

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.bundle import adjust, check_points
from pushbroom.algorithms.adjustment.control_series import control_point_series, farthest_points
from pushbroom.algorithms.adjustment.report import render_text, series_section
from pushbroom.algorithms.errors import CancelledError, InputError
from tests.helpers.adjustment_scene import IDS, LABELS, NAMES, point_observations, scene_models
from tests.helpers.feedback import Feedback


def test_farthest_points_take_the_corners_then_the_centre():
    """On a 5 x 5 grid of 1 km cells (shuffled), the first four are the corners and the fifth the
    centre; every prefix of a longer choice is the shorter choice; impossible counts are refused."""
    e, n = (v.ravel() for v in np.meshgrid(np.arange(5.0), np.arange(5.0)))
    order = np.random.default_rng(2).permutation(25)
    e, n = e[order], n[order]
    lon, lat = 10.0 + e * 1000.0 / 89_000.0, 45.0 + n * 1000.0 / 111_000.0
    chosen = farthest_points(lon, lat, 9)
    assert {(e[q], n[q]) for q in chosen[:4]} == {(0, 0), (0, 4), (4, 0), (4, 4)}
    assert (e[chosen[4]], n[chosen[4]]) == (2, 2)
    assert np.array_equal(farthest_points(lon, lat, 5), chosen[:5])
    assert len(set(chosen)) == 9
    for bad in (0, 26):
        with pytest.raises(InputError, match="cannot choose"):
            farthest_points(lon, lat, bad)


def test_series_rows_equal_direct_adjustments(small_scene):
    """Each row equals bundle.adjust + check_points with its control points (the other candidates
    left out), the check points stay the same, the input models are not edited, progress rises
    to 100 % and a cancel stops the series."""
    obs = point_observations(small_scene["points"], IDS, 5)
    models = scene_models(small_scene, NAMES)
    before = {i: m.orientation.corrections.look.copy() for i, m in models.items()}
    feedback = Feedback()
    rows = control_point_series(models, obs, [5, 3], ["look:0"], names=LABELS, height=300.0, feedback=feedback)
    assert [len(r.control) for r in rows] == [3, 5] and rows[1].control[:3] == rows[0].control
    assert all(np.array_equal(m.orientation.corrections.look, before[i]) for i, m in models.items())
    assert feedback.progress[-1] == 100.0 and np.all(np.diff(feedback.progress) >= 0)
    for row in rows:
        role = obs.points["role"].copy()
        role[(role == "control") & ~np.isin(obs.points["name"], row.control)] = "gone"
        used = obs.subset(role != "gone")
        result = adjust(scene_models(small_scene, NAMES), used, ["look:0"], names=LABELS, height=300.0)
        check = check_points(result, used, 300.0)
        rms = [np.sqrt(np.mean(check[k] ** 2)) for k in ("dE", "dN", "dH")]
        assert row.check == len(check["dE"]) == np.count_nonzero(obs.points["role"] == "check") > 1
        assert np.allclose(row.rms, rms, rtol=1e-9) and row.sigma0 == pytest.approx(result.sigma0, rel=1e-9)
    table = render_text([series_section(rows)]).splitlines()
    assert len(table) == 5 and table[2].split()[:2] == ["3", str(rows[0].check)]
    with pytest.raises(CancelledError):
        control_point_series(
            models, obs, [3, 5], ["look:0"], names=LABELS, height=300.0, feedback=Feedback(cancel_after=3)
        )
    with pytest.raises(InputError, match="within 1..5"):
        control_point_series(models, obs, [6], ["look:0"], names=LABELS)
    no_check = point_observations(small_scene["points"], IDS, 1000)
    with pytest.raises(InputError, match="needs check points"):
        control_point_series(models, no_check, [3], ["look:0"], names=LABELS)
