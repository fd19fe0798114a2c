"""Bundle adjustment (algorithms/adjustment): the Schur-reduced normal equations against a dense
numpy reference, recovery of injected look-angle errors, check points against their theoretical
precision, data snooping, and named datum defects; on a small simulated SPOT 5 triplet."""

import numpy as np
import pytest

from pushbroom.algorithms.adjustment import normals
from pushbroom.algorithms.adjustment.bundle import AdjustmentSettings, adjust, check_points
from pushbroom.algorithms.adjustment.observations import Observations
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.simulation import SceneConfig
from tests.helpers.adjustment_scene import (
    IDS,
    INJECTED,
    LABELS,
    NAMES,
    check_rms,
    perturbed,
    point_observations,
    scene_models,
    synthetic_points,
)


@pytest.fixture(scope="module")
def scene(simulated):
    """Supplied orientation = truth, 30 point candidates (0.3 px measurement noise)."""
    return simulated(SceneConfig.small(points=30, error_scale=0.0))


def dense_reference(start, a, b, l, w, img, col, wg, lg, nfree):
    """The same reduced normals from the full dense normal matrix (numpy), for the kernel test."""
    npts = start.size - 1
    n = 3 * npts + nfree
    rows, rhs, weights, image_row = [], [], [], []
    for p in range(npts):
        for j in range(start[p], start[p + 1]):
            for e in range(2):
                row = np.zeros(n)
                row[3 * p : 3 * p + 3] = a[j, e]
                for k in range(b.shape[2]):
                    if col[img[j], k] >= 0:
                        row[3 * npts + col[img[j], k]] += b[j, e, k]
                rows.append(row), rhs.append(l[j, e]), weights.append(w[j, e]), image_row.append(True)
        for r in range(3):
            if wg[p, r] > 0:
                row = np.zeros(n)
                row[3 * p + r] = 1.0
                rows.append(row), rhs.append(lg[p, r]), weights.append(wg[p, r]), image_row.append(False)
    design, rhs, weights = np.array(rows), np.array(rhs), np.array(weights)
    full = design.T @ (weights[:, None] * design)
    f = design.T @ (weights * rhs)
    npp, npo, noo = full[: 3 * npts, : 3 * npts], full[: 3 * npts, 3 * npts :], full[3 * npts :, 3 * npts :]
    inv = np.linalg.inv(npp)
    return (
        noo - npo.T @ inv @ npo,
        f[3 * npts :] - npo.T @ inv @ f[: 3 * npts],
        full,
        f,
        design,
        weights,
        np.array(image_row),
    )


def test_reduced_normals_and_redundancy_against_dense_reference():
    rng = np.random.default_rng(4)
    npts, per, nfree = 7, 3, 5
    start = np.arange(0, npts * per + 1, per)
    m = npts * per
    a, b = rng.normal(size=(m, 2, 3)), rng.normal(size=(m, 2, 32))
    l, w = rng.normal(size=(m, 2)), rng.uniform(0.5, 2.0, (m, 2))
    img = np.tile(np.arange(per), npts)
    col = np.full((per, 32), -1)
    col[0, :3], col[1, :2], col[2, [0, 5]] = [0, 1, 2], [3, 4], [2, 4]  # shared and fixed columns
    wg, lg = np.zeros((npts, 3)), np.zeros((npts, 3))
    wg[0], lg[0] = (4.0, 4.0, 1.0), (0.3, -0.2, 0.5)
    normal, rhs = np.zeros((nfree, nfree)), np.zeros(nfree)
    ninv, bp, ok = np.zeros((npts, 3, 3)), np.zeros((npts, 3)), np.zeros(npts, bool)
    design, points = normals.Design(start, a, b, w, img, col), normals.PointBlocks(ninv, bp, ok)
    normals.reduce_normals(design, l, normals.Ground(wg, lg), nfree, normal, rhs, points)
    ref_n, ref_b, full, f, dense, weights, image_rows = dense_reference(start, a, b, l, w, img, col, wg, lg, nfree)
    np.testing.assert_allclose(normal, ref_n, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(rhs, ref_b, rtol=1e-10, atol=1e-10)
    do = np.linalg.solve(normal, rhs)
    dx = np.zeros((npts, 3))
    normals.back_substitute(design, points, do, dx)
    np.testing.assert_allclose(np.concatenate([dx.ravel(), do]), np.linalg.solve(full, f), rtol=1e-9, atol=1e-9)
    qoo = np.linalg.inv(normal)
    qpp, red = np.zeros((npts, 3, 3)), np.zeros((m, 2))
    normals.point_statistics(design, points, qoo, qpp, red)
    q = np.linalg.inv(full)
    np.testing.assert_allclose(qpp, np.array([q[3 * p : 3 * p + 3, 3 * p : 3 * p + 3] for p in range(npts)]), rtol=1e-9)
    dense_r = 1.0 - np.einsum("ij,jk,ik->i", dense, q, dense) * weights
    np.testing.assert_allclose(red.ravel(), dense_r[image_rows], rtol=1e-9, atol=1e-12)
    assert dense_r.sum() == pytest.approx(len(weights) - 3 * npts - nfree)  # sum of r_i = redundancy


def test_scatter_partials_against_numpy():
    """The kernel that maps one image's partials to the compact columns, against the plain numpy."""
    rng = np.random.default_rng(8)
    n, nc, kk, total = 9, 32, 5, 20
    rows = np.sort(rng.choice(total, n, replace=False))
    d_corr, d_ground = rng.normal(size=(n, 2, nc)), rng.normal(size=(n, 2, 3))
    per_metre, cmap = rng.uniform(1e-5, 1.0, (n, 3)), rng.normal(size=(nc, kk)) * (rng.uniform(size=(nc, kk)) < 0.2)
    a, b = np.full((total, 2, 3), np.nan), np.full((total, 2, kk), np.nan)
    coef, cols = np.nonzero(cmap)
    normals.scatter_partials(rows, d_corr, d_ground, per_metre, coef, cols, cmap[coef, cols], b, a)
    # two orders of a sum of nc products: each within nc unit roundoffs of sum |products| (Higham's gamma_n)
    assert np.all(np.abs(b[rows] - d_corr @ cmap) <= nc * np.finfo(float).eps * (np.abs(d_corr) @ np.abs(cmap)))
    np.testing.assert_allclose(a[rows], d_ground * per_metre[:, None, :], rtol=1e-15)
    untouched = np.setdiff1d(np.arange(total), rows)
    assert np.isnan(a[untouched]).all() and np.isnan(b[untouched]).all()


def test_cholesky_solve_and_the_regularity_bound_against_numpy():
    """normals.cholesky_solve against numpy.linalg.solve on a badly scaled SPD system (Jacobi-scaled
    as in the adjustment), False on an indefinite one; bundle._clearly_regular only says regular
    where numpy's smallest eigenvalue is above the defect threshold, and does not say it for a
    nearly singular matrix."""
    from pushbroom.algorithms.adjustment.bundle import DEFECT_EIGENVALUE, _clearly_regular, _inverse_scaled

    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 12))
    scale = np.logspace(-6, 6, 12)
    m = a.T @ a * scale[:, None] * scale[None, :]
    rhs = rng.normal(size=(12, 3))
    d = 1.0 / np.sqrt(np.diag(m))
    scaled = m * d[:, None] * d[None, :]
    out = np.empty((12, 3))
    assert normals.cholesky_solve(scaled, rhs, out)
    np.testing.assert_allclose(out, np.linalg.solve(scaled, rhs), rtol=1e-10, atol=1e-12)
    ref = np.linalg.inv(scaled) * d[:, None] * d[None, :]
    np.testing.assert_allclose(_inverse_scaled(m), ref, rtol=1e-9, atol=0.0)
    assert not normals.cholesky_solve(np.diag([1.0, -1.0, 2.0]), np.eye(3), np.empty((3, 3)))
    assert _clearly_regular(scaled, DEFECT_EIGENVALUE)
    assert np.linalg.eigvalsh(scaled)[0] > DEFECT_EIGENVALUE * np.linalg.eigvalsh(scaled)[-1]
    near = scaled.copy()
    near[:, 0] = near[:, 1] * (1 + 1e-5)
    near[0, :] = near[1, :] * (1 + 1e-5)
    near[0, 0] = near[1, 1] * (1 + 1e-5) ** 2 + 1e-9
    assert not _clearly_regular(near, DEFECT_EIGENVALUE)


def test_recovers_injected_look_angles_and_check_points_match_their_precision(scene, figures):
    """19 control points (0.3 px, ground sigma 0.5 m) and 8 check points from the simulator, plus
    300 synthetic check points; free psi_x_0, psi_y_0 of every image."""
    obs = point_observations(scene["points"], IDS, 19)
    models = perturbed(scene)
    result = adjust(models, obs, ["look:0"], names=LABELS, height=300.0)
    for i, (dx, dy) in INJECTED.items():
        for kind, value in (("psi_x_0", dx), ("psi_y_0", dy)):
            q = result.parameters.select([f"{LABELS[i]} {kind}"]).argmax()
            assert abs(result.values[q] + value) < 2.0 * result.sigmas[q], (kind, result.values[q], result.sigmas[q])
            assert result.sigmas[q] < 2e-6
    assert 0.7 < result.sigma0 < 1.3  # 0.3 px noise against a priori 0.3 px
    assert result.redundancy == 2 * len(result.observations.measurements) + 3 * 19 - 3 * 19 - 6
    rms, theoretical = check_rms(result, synthetic_points(scene, IDS, 300, 0.3, 7), 300.0, figures)
    assert np.all((0.8 < rms / theoretical) & (rms / theoretical < 1.25))
    few = check_points(result, obs, height=300.0)
    assert len(few["dE"]) == len(obs.points) - 19 and np.all(np.abs(few["dH"]) < 5 * few["sigma"][:, 2])


def test_data_snooping_flags_and_removes_blunders(scene):
    obs = point_observations(scene["points"], IDS, 19)
    clean = adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)
    target = np.flatnonzero((obs.measurements["point"] == 4) & (obs.measurements["image_id"] == 2))[0]
    name = obs.points["name"][4]
    five = Observations(obs.points, obs.measurements.copy())
    five.measurements["col"][target] += 5.0
    result = adjust(perturbed(scene), five, ["look:0"], names=LABELS, height=300.0)
    worst = np.argmax(np.nanmax(np.abs(result.normalised), axis=1))
    assert result.observations.points["name"][result.observations.measurements["point"][worst]] == name
    assert worst in result.flagged()
    thirty = Observations(obs.points, obs.measurements.copy())
    thirty.measurements["row"][target] += 30.0
    fixed = adjust(
        perturbed(scene),
        thirty,
        ["look:0"],
        names=LABELS,
        height=300.0,
        settings=AdjustmentSettings(remove_blunders=True),
    )
    assert fixed.removed and fixed.removed[0][:2] == (name, 2)
    free = fixed.parameters.free
    assert np.all(np.abs(fixed.values[free] - clean.values[free]) < 2.0 * clean.sigmas[free])


def test_datum_defects_are_named(scene):
    obs = point_observations(scene["points"], IDS, 2)
    obs.points["role"][obs.points["role"] == "check"] = "tie"
    with pytest.raises(InputError, match=r"cannot be determined from these points: .*psi_.*Add control points"):
        adjust(perturbed(scene), obs, ["look:2"], names=LABELS, height=300.0)
    three = point_observations(scene["points"], IDS, 3)
    three.points["role"][three.points["role"] == "check"] = "tie"
    assert np.isfinite(adjust(perturbed(scene), three, ["look:2"], names=LABELS, height=300.0).sigma0)
    with pytest.raises(InputError, match="no orientation parameter matches"):
        adjust(perturbed(scene), obs, ["psi_z_0"], names=LABELS)


def test_no_redundancy_is_an_error(scene):
    """One control point in one image with that image's two look constants free: 5 observations for 5
    unknowns, solvable but with nothing to estimate sigma_0 from: a clear error, not NaN statistics."""
    obs = point_observations(scene["points"], IDS, 1)
    one = obs.subset(obs.points["role"] == "control")
    one = Observations(one.points, one.measurements[one.measurements["image_id"] == IDS["HRG"]])
    with pytest.raises(InputError, match="too few observations: 5 for 5 unknowns"):
        adjust(perturbed(scene), one, ["HRG psi_x_0", "HRG psi_y_0"], names=LABELS, height=300.0)
    assert adjust(perturbed(scene), one, ["HRG psi_x_0"], names=LABELS, height=300.0).redundancy == 1


def test_priors_pin_loosen_and_cure_defects(scene):
    """Prior observations x = 0: a tight one pins its unknown (and adds to the redundancy), a loose
    one changes nothing, and priors on the coefficients 2 control points cannot determine make
    the adjustment solvable with those coefficients no more uncertain than their priors."""
    obs = point_observations(scene["points"], IDS, 19)
    free = adjust(perturbed(scene), obs, ["look:0"], names=LABELS, height=300.0)
    q = free.parameters.select(["HRG psi_x_0"])
    pinned = adjust(
        perturbed(scene),
        obs,
        ["look:0"],
        names=LABELS,
        height=300.0,
        settings=AdjustmentSettings(priors={"HRG psi_x_0": 1e-10}),
    )
    assert abs(pinned.values[q][0]) < 1e-9 and pinned.redundancy == free.redundancy + 1
    assert abs(free.values[q][0]) > 10 * free.sigmas[q][0]
    loose = adjust(
        perturbed(scene),
        obs,
        ["look:0"],
        names=LABELS,
        height=300.0,
        settings=AdjustmentSettings(priors={"look:0": 1.0}),
    )
    m = free.parameters.free
    assert np.all(np.abs(loose.values[m] - free.values[m]) < 1e-3 * free.sigmas[m])
    two = point_observations(scene["points"], IDS, 2)
    two.points["role"][two.points["role"] == "check"] = "tie"
    higher = ["psi_x_12", "psi_y_12"]
    cured = adjust(
        perturbed(scene),
        two,
        ["look:2"],
        names=LABELS,
        height=300.0,
        settings=AdjustmentSettings(priors={p: 1e-5 for p in higher}),
    )
    held = cured.parameters.select(higher)
    assert np.isfinite(cured.sigma0) and np.all(cured.sigmas[held] <= 1e-5 * max(1.0, cured.sigma0))
    with pytest.raises(InputError, match="must be positive"):
        adjust(perturbed(scene), obs, ["look:0"], names=LABELS, settings=AdjustmentSettings(priors={"look:0": 0.0}))


def test_rpc_bias_correction_recovers_an_injected_affine_bias(scene):
    """RPCs fitted to the truth models, each given an affine image bias (shift 2-3 px, drift and
    scale 1 px per 1000 px); bias:affine with 19 control points recovers all 18 terms within 3
    sigma (18 terms: all within 2 sigma only with probability 0.4, within 3 sigma 0.95)."""
    from pushbroom.algorithms.sensors.rpc import RpcModel
    from pushbroom.algorithms.sensors.rpc_fit import fit_rpc

    injected = {
        1: [2.0, 0.5, -1.0, -3.0, 0.2, 1.0],
        2: [-2.5, -0.4, 0.8, 2.0, 0.6, -0.7],
        3: [1.0, 0.3, 0.5, 2.5, -0.5, 0.9],
    }
    models = {}
    for i, truth in scene_models(scene, NAMES, truth=True).items():
        rpc = fit_rpc(truth, (150.0, 750.0))[0]
        models[i] = RpcModel(rpc.coefficients, rpc.size, rpc.offset, LABELS[i], bias=injected[i])
    obs = point_observations(scene["points"], IDS, 19)
    result = adjust(models, obs, ["bias:affine"], names=LABELS, height=300.0)
    values = result.values[result.parameters.free].reshape(3, 6)
    sigmas = result.sigmas[result.parameters.free].reshape(3, 6)
    for k, i in enumerate(sorted(injected)):
        assert np.all(np.abs(values[k] + injected[i]) < 3.0 * sigmas[k]), (values[k], sigmas[k])
        np.testing.assert_allclose(models[i].bias, 0.0, atol=np.max(3 * sigmas[k]))


def test_report_gives_each_coefficient_its_maximum_effect(scene):
    """Kornus et al. 2006, Table 2: a look-angle offset of d rad moves HRG (near nadir, 5 m lines at ~830 km) by
    about d * 830 km / 5 m lines; every free unknown has a finite effect, fixed ones none."""
    from pushbroom.algorithms.adjustment.report import text_report

    result = adjust(
        perturbed(scene), point_observations(scene["points"], IDS, 19), ["look:0"], names=LABELS, height=300.0
    )
    q = [k for k in range(len(result.parameters)) if result.parameters.label(k) == "HRG psi_x_0"][0]
    assert result.effects[q] == pytest.approx(abs(result.values[q]) * 830e3 / 5.0, rel=0.15)
    assert np.all(np.isfinite(result.effects[result.parameters.free]))
    assert np.all(np.isnan(result.effects[~result.parameters.free]))
    assert "max. effect px" in text_report(result)


def test_variance_components_recover_the_groups_noise(scene, figures):
    """Tie points measured with 0.1 px noise but given 0.5 px a priori, control points 0.3 px as
    given: the estimated sigmas come back to the simulated noise, and the groups' redundancies add
    up to the block's."""
    from pushbroom.algorithms.adjustment import variance

    obs = point_observations(scene["points"], IDS, 19)
    tie = synthetic_points(scene, IDS, 400, 0.1, 11)
    tie.points["role"] = "tie"
    tie.measurements["sigma"] = 0.5
    both = obs.concatenate(tie)
    result, rescaled, components = variance.estimate(
        lambda o: adjust(perturbed(scene), o, ["look:0"], names=LABELS, height=300.0), both
    )
    by_group = {c.group: c for c in components}
    figures.table(
        "variance components", [{"group": g, "sigma": c.sigma, "redundancy": c.redundancy} for g, c in by_group.items()]
    )
    assert by_group["tie image"].sigma == pytest.approx(0.1, rel=0.1)
    assert by_group["control image"].sigma == pytest.approx(0.3, rel=0.3)
    assert sum(c.redundancy for c in components) == pytest.approx(result.redundancy, abs=1e-6)
    assert result.sigma0 == pytest.approx(1.0, abs=0.05)
    role = rescaled.points["role"][rescaled.measurements["point"]]
    assert np.allclose(rescaled.measurements["sigma"][role == "tie"], by_group["tie image"].sigma)


@pytest.mark.slow
def test_automatic_selection_on_a_small_block(scene, figures):
    """Kornus et al. 2006, section 3.4.3 on the 3 km block with 300 synthetic tie points: the injected
    look-angle constants are chosen (at most 2 others), every decision is logged, and the models carry the
    solution."""
    from pushbroom.algorithms.adjustment.selection import select_parameters

    tie = synthetic_points(scene, IDS, 300, 0.2, 5)
    tie.points["role"] = "tie"
    obs = point_observations(scene["points"], IDS, 19).concatenate(tie)
    models = perturbed(scene)
    selection = select_parameters(models, obs, names=LABELS, height=300.0)
    injected = {f"{LABELS[i]} {k}_0" for i in INJECTED for k in ("psi_x", "psi_y")}
    figures.report("selected free coefficients", selection.free)
    assert injected <= set(selection.free) and len(set(selection.free) - injected) <= 2
    assert any(line.startswith("step 1: fixed") for line in selection.log)
    assert selection.log[-1].startswith(f"selected {len(selection.free)} free coefficient(s)")
    for i, (_dx, _dy) in INJECTED.items():
        assert np.allclose(models[i].orientation.corrections.look[:, 0], 0.0, atol=2e-6)
