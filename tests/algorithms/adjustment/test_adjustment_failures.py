"""Failure modes of the bundle adjustment (issue 36), on the small simulated SPOT 5 triplet: a defect the
decomposition shows with a negative eigenvalue, or with an unknown of small scaled weight, is named; a NaN
never reaches the normal equations or the update (an error names the point or the unknowns instead); an
unmeasured control point takes no part; an unconverged solution says so; the control point screen names a
control point 1 km off and a measurement 40 px off, and nothing on clean points; the selection's t-test
threshold has the alpha of its normal quantile; the kernels' thread count does not change a result."""

import warnings

import numpy as np
import pytest

from pushbroom.algorithms.adjustment import normals
from pushbroom.algorithms.adjustment.bundle import (
    DEFECT_MEMBER,
    AdjustmentSettings,
    DefectError,
    _solve_jacobi,
    adjust,
    defect_groups,
)
from pushbroom.algorithms.adjustment.observations import Observations
from pushbroom.algorithms.adjustment.screening import describe, screen_control_points, without
from pushbroom.algorithms.adjustment.selection import t_threshold
from pushbroom.algorithms.errors import GeometryError, InputError
from pushbroom.algorithms.simulation import SceneConfig
from tests.helpers.adjustment_scene import IDS, LABELS, perturbed, point_observations


@pytest.fixture(scope="module")
def scene(simulated):
    """Supplied orientation = truth, 30 point candidates (0.3 px measurement noise); test_bundle.py's scene."""
    return simulated(SceneConfig.small(points=30, error_scale=0.0))


def test_an_exact_defect_with_a_negative_eigenvalue_is_named():
    """Rounding can leave an exact defect's eigenvalue slightly negative (-1.7e-16 in the issue's block);
    without priors it is a defect, never "held by the priors"."""
    normal = np.array([[1.0, 1.0 + 1e-15], [1.0 + 1e-15, 1.0]])
    assert np.linalg.eigvalsh(normal)[0] < 0.0  # the case: indefinite by rounding
    assert [sorted(g) for g in defect_groups(normal, ["a", "b"])] == [["a", "b"]]


def test_a_defect_names_the_unknown_whose_scaled_part_is_small():
    """A common roll equals the sum of three images' psi_y constants, whose columns nearly cancel (the
    points absorb the common part): in the correlation-scaled eigenvector the roll's share is small, yet
    fixing the roll is what cures the defect, so the group must name it."""
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(2, 40))
    s = 0.02 * rng.normal(size=40)
    design = np.column_stack([a + s / 3, b + s / 3, -(a + b) + s / 3, s, rng.normal(size=40)])
    normal = design.T @ design
    labels = ["psi_y HRG", "psi_y HRS1", "psi_y HRS2", "roll", "other"]
    d = 1.0 / np.sqrt(np.diag(normal))
    vec = np.linalg.eigh(normal * d[:, None] * d[None, :])[1][:, 0]
    assert DEFECT_MEMBER < abs(vec[3]) < 0.05  # small, though not 0: 0.05 was the old membership bound
    groups = defect_groups(normal, labels)
    assert len(groups) == 1 and set(groups[0]) == set(labels[:4])


def test_singular_normal_equations_in_an_iteration_are_a_named_defect():
    """Cholesky finding the matrix not positive definite (after the first iteration's defect test passed)
    is a DefectError naming the combination, not a LAPACK solve of a singular system."""
    normal = np.array([[4.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with pytest.raises(DefectError, match="x with y|y with x") as error:
        _solve_jacobi(normal, np.ones((3, 1)), ["x", "y", "z"], np.zeros(3))
    assert set(error.value.groups[0]) == {"x", "y"}


def test_a_control_point_where_the_models_give_no_position_is_named(scene):
    """A control point whose ground coordinates lie 30 degrees north of the scene: the sensor model gives
    NaN there. The adjustment names the point before anything is solved, with no numpy warning."""
    obs = point_observations(scene["points"], IDS, 19)
    bad = obs.points["name"][3]
    obs.points["lat"][3] += 30.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(GeometryError, match=f"points {bad}.*outside the models' valid domain"):
            adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)


def test_an_unmeasured_control_point_takes_no_part(scene):
    """Its measurements removed, a control point leaves the adjustment with a note, and the solution is the
    one without the point at all (an independent adjustment)."""
    obs = point_observations(scene["points"], IDS, 19)
    name = obs.points["name"][5]
    blank = Observations(obs.points, obs.measurements[obs.measurements["point"] != 5])
    result = adjust(perturbed(scene), blank, ["look:0"], names=LABELS, height=300.0)
    reference = adjust(perturbed(scene), obs.subset(obs.points["name"] != name), ["look:0"], names=LABELS, height=300.0)
    assert any(name in n and "take no part" in n for n in result.notes)
    assert name not in result.observations.points["name"]
    free = result.parameters.free
    np.testing.assert_allclose(result.values[free], reference.values[free], rtol=0, atol=1e-12)


def test_an_unconverged_solution_says_so(scene):
    """One Gauss-Newton iteration from 20 urad look-angle errors: the points still move by metres, so the
    result is flagged, with its last update; the same block converges with the default 15."""
    obs = point_observations(scene["points"], IDS, 19)
    one = adjust(
        perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0, settings=AdjustmentSettings(max_iterations=1)
    )
    assert not one.converged and one.iterations == 1 and one.last_update > 1e-4
    assert any(n.startswith("NOT CONVERGED in 1 iteration") for n in one.notes)
    full = adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)
    assert full.converged and full.last_update < 1e-4 and not full.notes


def test_a_measurement_without_coordinates_is_an_input_error(scene):
    obs = point_observations(scene["points"], IDS, 19)
    obs.measurements["col"][4] = np.nan
    with pytest.raises(InputError, match="has no image coordinates"):
        adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)


def test_the_screen_names_a_control_point_1_km_off_and_nothing_on_clean_points(scene):
    """19 control points with the supplied orientation 20 urad off (about 17 m, i.e. a shift per image):
    clean, nothing is suspect; one point moved 1 km north is suspect in all three images at 1000 m (the
    HRS images' 5 m rows and 10 m columns converted back to metres): its ground coordinates are wrong and
    it is left out; one measurement 40 px off in HRS1 is suspect there alone, as a measurement (left to
    data snooping)."""
    obs = point_observations(scene["points"], IDS, 19)
    models = perturbed(scene)
    assert not screen_control_points(models, obs).suspects
    far = Observations(obs.points.copy(), obs.measurements)
    far.points["lat"][2] += 1000.0 / 111_000.0
    screening = screen_control_points(models, far)
    assert {s.point for s in screening.suspects} == {2} and {s.image_id for s in screening.suspects} == {1, 2, 3}
    assert all(abs(s.offset_m - 1000.0) < 20.0 for s in screening.suspects)  # 1 km to within 2 %
    assert screening.ground_points() == {2} and "ground coordinates" in describe(screening, far, LABELS)
    kept = without(far, screening.ground_points())
    assert obs.points["name"][2] not in kept.points["name"] and len(kept.points) == len(obs.points) - 1
    slip = Observations(obs.points, obs.measurements.copy())
    k = np.flatnonzero((slip.measurements["point"] == 7) & (slip.measurements["image_id"] == 2))[0]
    slip.measurements["row"][k] += 40.0
    screening = screen_control_points(models, slip)
    assert [(s.point, s.image_id) for s in screening.suspects] == [(7, 2)]
    assert not screening.ground_points() and "measurement(s) there" in describe(screening, slip, LABELS)


def test_the_screen_needs_three_control_points_in_an_image(scene):
    """Of two control points that disagree, a median cannot tell which one is wrong: not screened."""
    obs = point_observations(scene["points"], IDS, 2)
    obs.points["lat"][0] += 1000.0 / 111_000.0
    assert not screen_control_points(perturbed(scene), obs).suspects
    three = point_observations(scene["points"], IDS, 3)
    three.points["lat"][0] += 1000.0 / 111_000.0
    assert {s.point for s in screen_control_points(perturbed(scene), three).suspects} == {0}


def test_the_t_threshold_has_the_alpha_of_its_normal_quantile():
    """|mean| / its sigma of 5 normal values exceeds t_threshold(3, 5) as often as a normal value exceeds
    3 (0.27 %), by simulation; with many values the threshold is the normal quantile itself."""
    rng = np.random.default_rng(11)
    x = rng.normal(size=(400_000, 5))
    t = np.abs(x.mean(axis=1)) / (x.std(axis=1, ddof=1) / np.sqrt(5))
    rate = np.mean(t > t_threshold(3.0, 5))
    assert abs(rate - 0.0027) < 4 * np.sqrt(0.0027 / 400_000)  # 4 binomial sigmas
    assert t_threshold(3.0, 10**6) == pytest.approx(3.0, abs=1e-4)
    assert t_threshold(3.0, 1) == np.inf


def test_results_do_not_depend_on_the_kernel_threads(scene, monkeypatch):
    """The same adjustment with the kernels on the calling thread and on all threads: bit for bit."""
    obs = point_observations(scene["points"], IDS, 19)
    monkeypatch.setattr(normals, "SERIAL_MEASUREMENTS", 10**9)
    serial = adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)
    monkeypatch.setattr(normals, "SERIAL_MEASUREMENTS", 0)
    parallel = adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)
    np.testing.assert_array_equal(serial.values, parallel.values)
    np.testing.assert_array_equal(serial.residuals, parallel.residuals)
