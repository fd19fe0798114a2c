"""`adjust` against an independent formulation of the same least-squares problem solved by
scipy.optimize.least_squares (tests/benchmarks/scipy_bundle.py, the benchmark's peer): the small
simulated SPOT 5 triplet, truth models with injected look-angle errors, 6 control points and 60
tie points, look:1 free (12 unknowns)."""
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_adjustment import FREE, INJECTED, LABELS, SCIPY_TOLERANCE, problem, supplied_models  # noqa: E402
from scipy_bundle import ScipyBundle  # noqa: E402

from pushbroom.algorithms.adjustment.bundle import adjust  # noqa: E402
from pushbroom.algorithms.geodesy import metres_per_degree  # noqa: E402


@pytest.fixture(scope="module")
def tiny(small_scene):
    obs = problem(small_scene, 60, control=6, seed=3)
    return small_scene, obs, float(np.nanmean(obs.points["h"]))


def test_scipy_jacobian_matches_finite_differences_of_its_residuals(tiny):
    """The peer's analytic sparse Jacobian (from the models' partials) is the derivative of its
    residual function (ground_to_image): central differences at a point off the start."""
    paths, obs, height = tiny
    peer = ScipyBundle(supplied_models(paths), obs, FREE, names=LABELS, height=height)
    rng = np.random.default_rng(5)
    z = np.concatenate([rng.normal(0, 2e-6, peer.nfree), rng.normal(0, 3.0, peer.size - peer.nfree)])
    jac = peer.jacobian(z).toarray()
    steps = np.where(np.arange(peer.size) < peer.nfree, 1e-7, 0.01)
    fd = np.column_stack([(peer.residuals(z + e) - peer.residuals(z - e)) / (2 * s)
                          for e, s in zip(np.diag(steps), steps)])
    np.testing.assert_allclose(jac, fd, rtol=1e-4, atol=1e-5 * np.abs(jac).max())


def test_adjust_and_scipy_least_squares_reach_the_same_solution(tiny):
    paths, obs, height = tiny
    ours = adjust(supplied_models(paths), obs, FREE, names=LABELS, height=height)
    x, lon, lat, h, result = ScipyBundle(supplied_models(paths), obs, FREE, names=LABELS, height=height).solve(SCIPY_TOLERANCE)
    assert result.success
    free = ours.parameters.free
    relative = np.abs(x - ours.values[free]) / ours.sigmas[free]
    east, north = metres_per_degree(ours.lat, ours.h)
    points = np.abs(np.column_stack([(lon - ours.lon) * east, (lat - ours.lat) * north, h - ours.h]))
    print(f"orientation: max |scipy - adjust| {relative.max():.2e} sigma; points {points.max():.2e} m")
    assert len(lon) == len(ours.lon) == 66
    assert relative.max() < 1e-6
    assert points.max() < 1e-5
    # the same minimum: v'Pv of adjust = 2 x scipy's cost (its residuals are already weighted)
    assert ours.sigma0 ** 2 * ours.redundancy == pytest.approx(2.0 * result.cost, rel=1e-9)
    # not a trivial problem: the injected errors are found
    for i, (dx, dy) in INJECTED.items():
        for kind, value in (("psi_x_0", dx), ("psi_y_0", dy)):
            q = [k for k in np.flatnonzero(free) if ours.parameters.label(k) == f"{LABELS[i]} {kind}"][0]
            assert abs(ours.values[q] + value) < 4.0 * ours.sigmas[q]
