"""Bundle adjustment (algorithms/adjustment): the Schur-reduced normal equations against a dense
numpy reference, recovery of injected look-angle errors, check points against their theoretical
precision, data snooping, and named datum defects; on a small simulated SPOT 5 triplet."""
import numpy as np
import pytest

from adjustment_scene import models_of, point_observations
from pushbroom.algorithms.adjustment import normals
from pushbroom.algorithms.adjustment.bundle import adjust, check_points, statistics_table
from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene

NAMES = ("HRG", "HRS1", "HRS2")
IDS = {n: k + 1 for k, n in enumerate(NAMES)}
LABELS = {k + 1: n for k, n in enumerate(NAMES)}
#: look-angle errors injected into the supplied models (rad): psi_x_0, psi_y_0 per image
INJECTED = {1: (2.0e-5, -1.0e-5), 2: (-1.5e-5, 0.8e-5), 3: (1.0e-5, 1.2e-5)}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """Supplied orientation = truth, 30 point candidates (0.3 px measurement noise)."""
    return simulate_scene(SceneConfig.small(points=30, error_scale=0.0), tmp_path_factory.mktemp("ba") / "s")


def perturbed(scene):
    models = models_of(scene, NAMES)
    for i, (dx, dy) in INJECTED.items():
        models[i].orientation.corrections.look[:, 0] = (dx, dy)
    return models


def synthetic_points(scene, n, sigma_px, seed):
    """n ground points on the true DSM seen in the three images (truth models), image noise sigma_px."""
    rng = np.random.default_rng(seed)
    truth = models_of(scene, NAMES, truth=True)
    cols, rows = truth[1].size
    x, y = rng.uniform(30, cols - 30, n), rng.uniform(30, rows - 30, n)
    lon, lat, h = truth[1].image_to_dem(x, y, Dem.from_file(scene["dsm"]))
    meas = []
    for i, model in truth.items():
        c, r = model.ground_to_image(lon, lat, h)
        c, r = c + rng.normal(0, sigma_px, n), r + rng.normal(0, sigma_px, n)
        meas += [(k, i, c[k], r[k], sigma_px) for k in range(n)]
    points = np.zeros(n, POINT_DTYPE)
    points["name"] = [f"S{k}" for k in range(n)]
    points["role"], points["lon"], points["lat"], points["h"] = "check", lon, lat, h
    return Observations(points, np.array(meas, MEAS_DTYPE))


def dense_reference(start, a, b, l, w, img, col, wg, lg, nfree):
    """The same reduced normals from the full dense normal matrix (numpy), for the kernel test."""
    npts = start.size - 1
    n = 3 * npts + nfree
    rows, rhs, weights, image_row = [], [], [], []
    for p in range(npts):
        for j in range(start[p], start[p + 1]):
            for e in range(2):
                row = np.zeros(n)
                row[3 * p:3 * p + 3] = a[j, e]
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
    npp, npo, noo = full[:3 * npts, :3 * npts], full[:3 * npts, 3 * npts:], full[3 * npts:, 3 * npts:]
    inv = np.linalg.inv(npp)
    return noo - npo.T @ inv @ npo, f[3 * npts:] - npo.T @ inv @ f[:3 * npts], full, f, design, weights, \
        np.array(image_row)


def test_reduced_normals_and_redundancy_against_dense_reference():
    rng = np.random.default_rng(4)
    npts, per, nfree = 7, 3, 5
    start = np.arange(0, npts * per + 1, per)
    m = npts * per
    a, b = rng.normal(size=(m, 2, 3)), rng.normal(size=(m, 2, 32))
    l, w = rng.normal(size=(m, 2)), rng.uniform(0.5, 2.0, (m, 2))
    img = np.tile(np.arange(per), npts)
    col = np.full((per, 32), -1)
    col[0, :3], col[1, :2], col[2, [0, 5]] = [0, 1, 2], [3, 4], [2, 4]     # shared and fixed columns
    wg, lg = np.zeros((npts, 3)), np.zeros((npts, 3))
    wg[0], lg[0] = (4.0, 4.0, 1.0), (0.3, -0.2, 0.5)
    normal, rhs = np.zeros((nfree, nfree)), np.zeros(nfree)
    ninv, bp, ok = np.zeros((npts, 3, 3)), np.zeros((npts, 3)), np.zeros(npts, bool)
    normals.reduce_normals(start, a, b, l, w, img, col, wg, lg, nfree, normal, rhs, ninv, bp, ok)
    ref_n, ref_b, full, f, design, weights, image_rows = dense_reference(start, a, b, l, w, img, col, wg, lg, nfree)
    np.testing.assert_allclose(normal, ref_n, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(rhs, ref_b, rtol=1e-10, atol=1e-10)
    do = np.linalg.solve(normal, rhs)
    dx = np.zeros((npts, 3))
    normals.back_substitute(start, a, b, w, img, col, ninv, bp, ok, do, dx)
    np.testing.assert_allclose(np.concatenate([dx.ravel(), do]), np.linalg.solve(full, f), rtol=1e-9, atol=1e-9)
    qoo = np.linalg.inv(normal)
    qpp, red = np.zeros((npts, 3, 3)), np.zeros((m, 2))
    normals.point_statistics(start, a, b, w, img, col, ninv, ok, qoo, qpp, red)
    q = np.linalg.inv(full)
    np.testing.assert_allclose(qpp, np.array([q[3 * p:3 * p + 3, 3 * p:3 * p + 3] for p in range(npts)]), rtol=1e-9)
    dense_r = 1.0 - np.einsum("ij,jk,ik->i", design, q, design) * weights
    np.testing.assert_allclose(red.ravel(), dense_r[image_rows], rtol=1e-9, atol=1e-12)
    assert dense_r.sum() == pytest.approx(len(weights) - 3 * npts - nfree)    # sum of r_i = redundancy


def test_recovers_injected_look_angles_and_check_points_match_their_precision(scene):
    """19 control points (0.3 px, ground sigma 0.5 m) and 8 check points from the simulator, plus
    300 synthetic check points; free psi_x_0, psi_y_0 of every image."""
    obs = point_observations(scene["points"], IDS, 19)
    models = perturbed(scene)
    result = adjust(models, obs, ["look:0"], names=LABELS, height=300.0)
    for i, (dx, dy) in INJECTED.items():
        for kind, value in (("psi_x_0", dx), ("psi_y_0", dy)):
            q = [k for k in np.flatnonzero(result.parameters.free) if result.parameters.label(k) == f"{LABELS[i]} {kind}"][0]
            assert abs(result.values[q] + value) < 2.0 * result.sigmas[q], (kind, result.values[q], result.sigmas[q])
            assert result.sigmas[q] < 2e-6
    assert 0.7 < result.sigma0 < 1.3          # 0.3 px noise against a priori 0.3 px
    assert result.redundancy == 2 * len(result.observations.measurements) + 3 * 19 - 3 * 19 - 6
    check = check_points(result, synthetic_points(scene, 300, 0.3, 7), height=300.0)
    table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")})
    theoretical = np.sqrt(np.mean(check["sigma"] ** 2, axis=0))
    for k, key in enumerate(("dE", "dN", "dH")):
        print(f"{key}: RMS {table[key][4]:.3f} m, theoretical {theoretical[k]:.3f} m")
        assert 0.8 < table[key][4] / theoretical[k] < 1.25
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
    fixed = adjust(perturbed(scene), thirty, ["look:0"], names=LABELS, height=300.0, remove_blunders=True)
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


def test_rpc_bias_correction_recovers_an_injected_affine_bias(scene):
    """RPCs fitted to the truth models, each given an affine image bias (shift 2-3 px, drift and
    scale 1 px per 1000 px); bias:affine with 19 control points recovers all 18 terms within 3
    sigma (18 terms: all within 2 sigma only with probability 0.4, within 3 sigma 0.95)."""
    from pushbroom.algorithms.sensors.rpc import RpcModel
    from pushbroom.algorithms.sensors.rpc_fit import fit_rpc
    injected = {1: [2.0, 0.5, -1.0, -3.0, 0.2, 1.0], 2: [-2.5, -0.4, 0.8, 2.0, 0.6, -0.7],
                3: [1.0, 0.3, 0.5, 2.5, -0.5, 0.9]}
    models = {}
    for i, truth in models_of(scene, NAMES, truth=True).items():
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
    """K Table 2: a look-angle offset of d rad moves HRG (near nadir, 5 m lines at ~830 km) by
    about d * 830 km / 5 m lines; every free unknown has a finite effect, fixed ones none."""
    from pushbroom.algorithms.adjustment.report import text_report
    result = adjust(perturbed(scene), point_observations(scene["points"], IDS, 19), ["look:0"], names=LABELS,
                    height=300.0)
    q = [k for k in range(len(result.parameters)) if result.parameters.label(k) == "HRG psi_x_0"][0]
    assert result.effects[q] == pytest.approx(abs(result.values[q]) * 830e3 / 5.0, rel=0.15)
    assert np.all(np.isfinite(result.effects[result.parameters.free]))
    assert np.all(np.isnan(result.effects[~result.parameters.free]))
    assert "max. effect px" in text_report(result)
