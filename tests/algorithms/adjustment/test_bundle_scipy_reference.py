"""`adjust` against an independent formulation of the same least-squares problem solved by
scipy.optimize.least_squares (tests/helpers/scipy_bundle.py, the benchmark's peer): the small
simulated SPOT 5 triplet, truth models with injected look-angle errors, 6 control points and 60
tie points, look:1 free (12 unknowns)."""

import numpy as np
import pytest

from pushbroom.algorithms.adjustment.bundle import AdjustmentSettings, adjust
from pushbroom.algorithms.geodesy import B, metres_per_degree
from tests.benchmarks.bench_adjustment import FREE, INJECTED, LABELS, SCIPY_TOLERANCE, problem, supplied_models
from tests.helpers.scipy_bundle import ScipyBundle

ADJUST_TOLERANCE = 1e-4  # m, adjust's default stop: the largest point update


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
    fd = np.column_stack(
        [(peer.residuals(z + e) - peer.residuals(z - e)) / (2 * s) for e, s in zip(np.diag(steps), steps)]
    )
    np.testing.assert_allclose(jac, fd, rtol=1e-4, atol=1e-5 * np.abs(jac).max())


def test_adjust_and_scipy_least_squares_reach_the_same_solution(tiny):
    """The same minimum, within what the two solvers' stops and the formulations' one difference allow.

    A change dl of the (weighted) observations moves every unknown by at most ||dl||_P / s0 of its
    sigma (Cauchy-Schwarz on N^-1 A'P dl). scipy stops when a step no longer lowers its cost F by
    ftol F (or moves z by xtol |z|): F within about ftol F of the minimum's, so (dz'N dz <= 2 ftol F,
    s0^2 = 2 F / r) within about sqrt(ftol r) sigma. The formulations' control
    point misclosures in E, N differ by their metres per degree (scipy's at the start, adjust's at the
    current point; a control point moves by its ground residual v_ground): relatively by at most
    (1 + tan(lat)) |v_ground| / B. adjust stops when its largest point update is below its tolerance;
    Gauss-Newton's remaining error is below that update (it shrinks by orders of magnitude per
    iteration here), i.e. tolerance / sigma_p of the points' sigmas, and the orientation solved with
    them converges alike. The figures move with the BLAS kernels: 1.4e-8 sigma and 1.7e-8 m here,
    1.9e-6 sigma and 1.6e-5 m with OPENBLAS_CORETYPE=Haswell (an AMD EPYC's). Wrong solutions fall
    outside: one iteration short, 1 % on one image's sigmas or twice the control heights' sigma miss
    the points' and v'Pv's bounds by 50 x or more, the orientation's by 1.9 x or more."""
    paths, obs, height = tiny
    ours = adjust(
        supplied_models(paths),
        obs,
        FREE,
        names=LABELS,
        height=height,
        settings=AdjustmentSettings(tolerance=ADJUST_TOLERANCE),
    )
    bundle = ScipyBundle(supplied_models(paths), obs, FREE, names=LABELS, height=height)
    x, lon, lat, h, result = bundle.solve(SCIPY_TOLERANCE)
    assert result.success
    free = ours.parameters.free
    relative = np.abs(x - ours.values[free]) / ours.sigmas[free]
    east, north = metres_per_degree(ours.lat, ours.h)
    points = np.abs(np.column_stack([(lon - ours.lon) * east, (lat - ours.lat) * north, h - ours.h]))
    assert len(lon) == len(ours.lon) == 66
    r, vpv = ours.redundancy, ours.sigma0**2 * ours.redundancy
    ground = ours.ground_residuals  # control points: observed - adjusted E, N, U (m)
    sigma_en = np.column_stack([ours.observations.points["sigma_e"], ours.observations.points["sigma_n"]])
    vpv_ground = np.nansum((ground[:, :2] / sigma_en) ** 2)
    per_degree = (1.0 + np.tan(np.radians(np.abs(ours.lat).max()))) * np.nanmax(np.abs(ground)) / B
    # scipy's stop plus the formulations' difference, in sigmas of any unknown (docstring): 4.6e-6 here
    solvers = np.sqrt(SCIPY_TOLERANCE * r) + per_degree * np.sqrt(vpv_ground) / ours.sigma0
    # ... plus adjust's stop, tolerance / smallest point sigma: 2.4e-4 here, the injected psi_x 11-40 sigma
    bound = solvers + ADJUST_TOLERANCE / ours.point_sigmas.min()
    assert relative.max() < bound
    # adjust's stop in metres plus the rest in the largest point sigma: 1.2e-4 m here
    assert points.max() < ADJUST_TOLERANCE + solvers * ours.point_sigmas.max()
    # the same minimum: v'Pv of adjust = 2 x scipy's cost (its residuals are already weighted), to the
    # first-order change of the ground misclosures' squares plus a solution `bound` off (bound^2 / r): 1.4e-9 here
    assert vpv == pytest.approx(2.0 * result.cost, rel=2.0 * per_degree * vpv_ground / vpv + bound**2 / r)
    # not a trivial problem: the injected errors are found
    for i, (dx, dy) in INJECTED.items():
        for kind, value in (("psi_x_0", dx), ("psi_y_0", dy)):
            q = [k for k in np.flatnonzero(free) if ours.parameters.label(k) == f"{LABELS[i]} {kind}"][0]
            assert abs(ours.values[q] + value) < 4.0 * ours.sigmas[q]
