"""Automatic parameter selection (algorithms/adjustment/selection.py, Kornus et al. 2006, section 3.4.3) on a
simulated SPOT 5 triplet whose supplied orientation is the truth plus known errors, adjusted from 19 control
points and tie points measured with known noise in the true images (adjustment_scene.synthetic_points: the
selection is under test here; matched tie points feed it in test_end_to_end.py, whose chain selects the parameters
of region growing's tie points).

The errors (about 30 m on the ground) are look-angle offsets and a scale term as in Kornus et al. 2006, Table 2
and an attitude (roll) drift common to the pass. They are chosen to be identifiable: a constant
attitude or position error of the pass moves each image like its own look-angle constants do, so
no adjustment can tell those apart (the simulator's default perturbation contains such errors;
test_bundle.py covers it), whereas a drift also shows inside each image."""

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.observations import Observations
from pushbroom.algorithms.adjustment.parameters import OrientationParameters
from pushbroom.algorithms.adjustment.selection import select_parameters
from pushbroom.algorithms.simulation import SceneConfig
from tests.helpers.adjustment_scene import (
    IDS,
    LABELS,
    NAMES,
    check_rms,
    point_observations,
    scene_models,
    synthetic_points,
)

pytestmark = pytest.mark.slow

PASS = "pass HRS1+HRG+HRS2"  # the trajectory, its images in time order
#: injected corrections (rad; roll drift in rad per time_scale = 10 s): supplied = truth - these
INJECTED = {
    "HRG psi_x_0": 2.8e-5,
    "HRG psi_y_0": -1.2e-5,
    "HRG psi_y_1": 8e-6,
    "HRS1 psi_x_0": 1.5e-5,
    "HRS2 psi_y_0": 1.0e-5,
    f"{PASS} roll_1": 1.0e-5,
}
#: synthetic tie points (block's docstring): how many, and their image noise (px)
TIE_POINTS, TIE_SIGMA = 1500, 0.2


@pytest.fixture(scope="module")
def block(simulated):
    """A 20 km scene (supplied = truth) on a 20 m ground grid (its images are not read), 30 point candidates;
    TIE_POINTS tie points spread over the HRG image, measured in the three images with TIE_SIGMA px of noise
    (about one per 100 x 100 HRG pixels, and the precision of region growing's LSM)."""
    paths = simulated(SceneConfig(size_km=20.0, points=30, error_scale=0.0, grid_m=20.0))
    tie = synthetic_points(paths, IDS, TIE_POINTS, TIE_SIGMA, 13)
    tie.points["role"] = "tie"
    return paths, point_observations(paths["points"], IDS, 19).concatenate(tie)


def perturbed(paths, names):
    models = scene_models(paths, NAMES)
    params = OrientationParameters(models, LABELS)
    x = np.zeros(len(params))
    for name, value in INJECTED.items():
        x[params.select([name])] = -value
    params.apply(x)
    return {IDS[n]: models[IDS[n]] for n in names}


def test_selection_frees_the_injected_coefficients_and_recovers_them(block, figures):
    paths, obs = block
    selection = select_parameters(perturbed(paths, NAMES), obs, names=LABELS, height=300.0)
    result = selection.result
    free = set(selection.free)
    figures.report("selected free coefficients", sorted(free))
    for line in selection.log:
        figures.report("selection log", line)
    assert set(INJECTED) <= free and len(free - set(INJECTED)) <= 2
    params = result.parameters
    for name, value in INJECTED.items():
        q = params.select([name]).argmax()
        figures.report(f"{name} estimated", result.values[q], note=f"+- {result.sigmas[q]:.2g}, injected {value:.4g}")
        assert abs(result.values[q] - value) < 2.0 * result.sigmas[q]
    rms, theoretical = check_rms(result, synthetic_points(paths, IDS, 300, 0.3, 7), 300.0, figures)
    assert np.all((0.8 < rms / theoretical) & (rms / theoretical < 1.2))


def test_hrs_only_solves_with_a_larger_planimetric_error(block, figures):
    """Kornus et al. 2006, section 3.4.3.2 / Table 3: without the nadir HRG the block still solves; the
    planimetric check point error grows (same 300 check points, measured in HRS1 and HRS2 only)."""
    paths, obs = block
    results = {}
    for label, names in (("HRG+HRS", NAMES), ("HRS only", NAMES[1:])):
        ids = {n: IDS[n] for n in names}
        sub = Observations(obs.points, obs.measurements[np.isin(obs.measurements["image_id"], list(ids.values()))])
        selection = select_parameters(perturbed(paths, names), sub, names=LABELS, height=300.0)
        figures.report(f"{label}: selected free coefficients", selection.free)
        results[label], _ = check_rms(
            selection.result, synthetic_points(paths, ids, 300, 0.3, 7), 300.0, figures, f"{label} check points"
        )
    assert np.hypot(*results["HRS only"][:2]) > np.hypot(*results["HRG+HRS"][:2])
