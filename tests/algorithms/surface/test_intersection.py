"""Forward intersection (algorithms/surface/intersection.py) on the simulated SPOT 5 triplet with its
truth models: ground points on the true DSM, projected into the images with the truth models, with
and without Gaussian image noise; RPC models fitted to the truth models; the Pleiades triplet."""

import dataclasses
import time

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.geodesy import ecef_to_geodetic, geodetic_to_ecef, metres_per_degree
from pushbroom.algorithms.sensors.rpc_fit import fit_rpc
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.surface import intersection as ix
from tests.helpers.feedback import Feedback

NAMES = ("HRG", "HRS1", "HRS2")
N_POINTS = 3000


@pytest.fixture(scope="module")
def scene(small_scene):
    """Truth models and N_POINTS ground points on the DSM seen inside all three images."""
    paths = small_scene
    models = {name: sensors.load(paths["truth_metadata"][name]) for name in NAMES}
    dsm = read_dem(paths["dsm"])
    rng = np.random.default_rng(3)
    cols, rows = models["HRG"].size
    col, row = rng.uniform(0, cols, 2 * N_POINTS), rng.uniform(0, rows, 2 * N_POINTS)
    lon, lat, h = models["HRG"].image_to_dem(col, row, dsm)
    inside = np.ones(lon.size, bool)
    for model in models.values():
        c, r = model.ground_to_image(lon, lat, h)
        inside &= (c > 2) & (c < model.size[0] - 2) & (r > 2) & (r < model.size[1] - 2)
    keep = np.flatnonzero(inside)[:N_POINTS]
    assert keep.size == N_POINTS
    return {"models": models, "lon": lon[keep], "lat": lat[keep], "h": h[keep], "dsm": dsm}


def measure(models, names, lon, lat, h, noise=0.0, seed=0):
    """(image ids, point index, col, row) of ground points in the images `names` (ids = names)."""
    rng = np.random.default_rng(seed)
    n = lon.size
    image, point, cols, rows = [], [], [], []
    for name in names:
        c, r = models[name].ground_to_image(lon, lat, h)
        image.append(np.full(n, name))
        point.append(np.arange(n))
        cols.append(c + rng.normal(0.0, noise, n) if noise else c)
        rows.append(r + rng.normal(0.0, noise, n) if noise else r)
    return np.concatenate(image), np.concatenate(point), np.concatenate(cols), np.concatenate(rows)


def errors_enu(result, lon, lat, h):
    """(n, 3) errors in metres east, north, up of the intersected points against the truth."""
    me, mn = metres_per_degree(float(np.mean(lat)))
    return np.column_stack([(result.lon - lon) * me, (result.lat - lat) * mn, result.h - h])


def test_closest_to_lines_kernel_against_numpy():
    """Groups of 1-4 random lines (some parallel, some with a NaN end) against the normal equations
    solved in numpy."""
    rng = np.random.default_rng(11)
    counts = rng.integers(1, 5, 300)
    bounds = np.r_[0, np.cumsum(counts)]
    p0, p1 = rng.normal(0, 1e3, (bounds[-1], 3)), rng.normal(0, 1e3, (bounds[-1], 3))
    p0[5] = np.nan
    p1[bounds[7] : bounds[8]] = p0[bounds[7] : bounds[8]] + [1.0, 2.0, 3.0]  # parallel lines
    xyz, ok = np.empty((counts.size, 3)), np.zeros(counts.size, bool)
    ix.closest_to_lines(p0, p1, bounds, ix.SINGULAR_RATIO, xyz, ok)
    for g in range(counts.size):
        lines = [
            (a, b)
            for a, b in zip(p0[bounds[g] : bounds[g + 1]], p1[bounds[g] : bounds[g + 1]])
            if np.isfinite(a).all() and np.isfinite(b).all()
        ]
        u = [(b - a) / np.linalg.norm(b - a) for a, b in lines]
        normal = sum((np.eye(3) - np.outer(v, v) for v in u), np.zeros((3, 3)))
        want_ok = len(lines) >= 2 and np.linalg.det(normal) > ix.SINGULAR_RATIO * np.prod(np.diag(normal))
        assert ok[g] == want_ok, g
        if want_ok:
            rhs = sum((np.eye(3) - np.outer(v, v)) @ (0.5 * (a + b)) for v, (a, b) in zip(u, lines))
            np.testing.assert_allclose(xyz[g], np.linalg.solve(normal, rhs), rtol=1e-9, atol=1e-6)
        elif lines:
            np.testing.assert_allclose(xyz[g], 0.5 * (lines[0][0] + lines[0][1]))
        else:
            assert np.isnan(xyz[g]).all()
    assert not ok[7] and ok.sum() > 200


def test_closest_points_of_exact_lines_of_sight_are_the_truth_and_refuse_single_rays(scene, figures):
    """The start alone (the adjustment's starting points): exact measurements' lines of sight meet in
    the true point, the same from SpotModel.ray_points (line of sight) as from SensorModel's (two
    ground points per ray); with 0.3 px noise the start is metres close; a point with fewer than two
    images' lines is not usable."""
    models, truth = scene["models"], (scene["lon"], scene["lat"], scene["h"])
    image, point, col, row = measure(models, NAMES, *truth)
    me, mn = metres_per_degree(float(np.mean(scene["lat"])))

    def error(lon, lat, h):
        return np.column_stack([(lon - truth[0]) * me, (lat - truth[1]) * mn, h - truth[2]])

    ids, lon, lat, h, ok = ix.closest_points(models, image, 5 * point, col, row)
    assert np.array_equal(ids, 5 * np.arange(N_POINTS)) and ok.all()
    exact = np.abs(error(lon, lat, h)).max()
    noise = np.random.default_rng(2).normal(0.0, 0.3, (2, col.size))
    noisy = np.sqrt(
        np.mean(error(*ix.closest_points(models, image, point, col + noise[0], row + noise[1])[1:4]) ** 2, axis=0)
    )
    figures.report("closest points of exact lines of sight, largest error", exact, "m")
    figures.report("closest points with 0.3 px noise, RMS E, N, H", noisy, "m")
    assert exact < 1e-3
    assert noisy.max() < 5.0

    class TwoHeights(sensors.SensorModel):  # SensorModel.ray_points: rays through two ground points
        def __init__(self, model):
            self.image_to_ground_or_nan, self.size = model.image_to_ground_or_nan, model.size

    plain = ix.closest_points({k: TwoHeights(m) for k, m in models.items()}, image, 5 * point, col, row)
    assert np.array_equal(plain[4], ok)
    assert np.abs(error(*plain[1:4]) - error(lon, lat, h)).max() < 1e-6
    first = np.flatnonzero(point == 0)[0]
    single = ix.closest_points(models, image[[first, first]], [0, 1], col[[first, first]], row[[first, first]])
    assert not single[4].any()


@pytest.mark.parametrize("names", [NAMES, ("HRG", "HRS1"), ("HRS1", "HRS2")])
def test_exact_measurements_give_the_truth(scene, names, figures):
    models = scene["models"]
    result = ix.intersect(
        models, ix.Measurements(*measure(models, names, scene["lon"], scene["lat"], scene["h"]), sigma=0.5)
    )
    assert result.status_counts() == {"converged": N_POINTS}
    assert np.all(result.rays == len(names))
    err = errors_enu(result, scene["lon"], scene["lat"], scene["h"])
    figures.report("largest error", np.abs(err).max(), "m")
    assert np.abs(err).max() < 1e-3
    assert np.all(result.sigma0 < 1e-4) and np.all(result.rms < 1e-5)


def test_noisy_measurements_agree_with_the_predicted_sigmas(scene, figures):
    """Empirical RMS of the normalised errors per axis between 0.8 and 1.25, E[sigma0^2] = 1, and
    the third ray sharpens the height (K: three-ray points are the best)."""
    models, truth = scene["models"], (scene["lon"], scene["lat"], scene["h"])
    noise = 0.1
    sigma_h = {}
    for names in (NAMES, ("HRG", "HRS1")):
        result = ix.intersect(
            models, ix.Measurements(*measure(models, names, *truth, noise=noise, seed=len(names)), sigma=noise)
        )
        assert result.status_counts() == {"converged": N_POINTS}
        ratio = np.sqrt(np.mean((errors_enu(result, *truth) / result.sigma) ** 2, axis=0))
        mean_var = np.mean(result.sigma0**2)
        figures.report(f"{'-'.join(names)}: RMS(error / sigma) E, N, H", ratio)
        figures.report(f"{'-'.join(names)}: mean sigma0^2", mean_var)
        figures.report(f"{'-'.join(names)}: median sigma E, N, H", np.median(result.sigma, axis=0), "m")
        assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio
        assert 0.9 < mean_var < 1.1
        # image residual RMS: E[v'v] = r sigma^2 over the 2k coordinates
        expected = noise * np.sqrt((2 * len(names) - 3) / (2 * len(names)))
        assert abs(np.sqrt(np.mean(result.rms**2)) / expected - 1) < 0.1
        sigma_h[len(names)] = result.sigma[:, 2]
    assert np.all(sigma_h[3] < sigma_h[2])


def reference_intersection(models, names, cols, rows, start, iterations=6, step=0.1):
    """Independent reference: Gauss-Newton on the image residuals with unknowns in ECEF metres and
    the Jacobian by central differences (+-`step` m) of ground_to_image alone (the true minimum of
    the image residuals; no partials, no local frame), from `start` (lon, lat, h)."""
    xyz = geodetic_to_ecef(*start)

    def residuals(x):
        ground = ecef_to_geodetic(x)
        return np.concatenate(
            [np.subtract(models[n].ground_to_image(*ground), (c, r)) for n, c, r in zip(names, cols, rows)]
        )

    for _ in range(iterations):
        jac = np.column_stack([(residuals(xyz + e) - residuals(xyz - e)) / (2 * step) for e in np.eye(3) * step])
        xyz = xyz - np.linalg.lstsq(jac, residuals(xyz), rcond=None)[0]
    return ecef_to_geodetic(xyz)


@pytest.fixture(scope="module")
def pair(simulated):
    """Truth models of a simulated SPOT 1-4 pair (look angles linear across the array) and ground
    points on its DSM."""
    paths = simulated(SceneConfig.small(configuration="spot14_pair"))
    models = {name: sensors.load(path) for name, path in paths["truth_metadata"].items()}
    first = models["HRV1_A"]
    c, r = np.meshgrid(np.linspace(0.3, 0.7, 3) * first.size[0], np.linspace(0.3, 0.7, 2) * first.size[1])
    lon, lat, h = first.image_to_dem(c.ravel(), r.ravel(), read_dem(paths["dsm"]))
    return {"models": models, "lon": lon, "lat": lat, "h": h}


@pytest.mark.parametrize("case, tolerance", [("spot14", 1e-6), ("rpc", 1e-6), ("spot5", 1e-4)])
def test_agrees_with_an_independent_solution(scene, pair, rpcs, case, tolerance, figures):
    """Against reference_intersection on 6 points with 0.3 px noise: to 1e-6 m with the rigorous
    SPOT 1-4 pair and with RPC models; with SPOT 5 (per-detector look-angle tables) to about 1e-5 m
    only: SpotModel.partials takes the look angles' derivative along the array by a +-0.5 px
    difference, which spans a knot of the piecewise linear table and averages two slopes; its row
    partials are off by up to about 1e-5 relative, which moves the least-squares point by that
    fraction of residual x pixel size. (scipy's least_squares was tried as the reference: its
    finite-difference runs stop 1e-6 to 1e-5 m apart from each other on these models.)"""
    if case == "spot14":
        models, truth = pair["models"], (pair["lon"], pair["lat"], pair["h"])
    else:
        models = scene["models"] if case == "spot5" else rpcs
        truth = scene["lon"][:6], scene["lat"][:6], scene["h"][:6]
    image, point, col, row = measure(models, tuple(models), *truth, noise=0.3, seed=7)
    result = ix.intersect(models, ix.Measurements(image, point, col, row, 0.3))
    assert result.status_counts() == {"converged": 6}
    me, mn = metres_per_degree(float(truth[1][0]))
    worst = 0.0
    for p in range(6):
        sel = point == p
        ref = reference_intersection(
            models, image[sel], col[sel], row[sel], (truth[0][p] + 2e-5, truth[1][p] - 3e-5, truth[2][p] + 4.0)
        )
        worst = max(
            worst, np.abs([(result.lon[p] - ref[0]) * me, (result.lat[p] - ref[1]) * mn, result.h[p] - ref[2]]).max()
        )
    figures.report("largest difference to the independent solution", worst, "m")
    assert worst < tolerance


def test_any_point_ids_and_order_and_chunks(scene, monkeypatch):
    """Point ids need not be 0..n-1 nor the measurements sorted; chunking changes nothing."""
    models = scene["models"]
    truth = scene["lon"][:50], scene["lat"][:50], scene["h"][:50]
    image, point, col, row = measure(models, NAMES, *truth, noise=0.2)
    plain = ix.intersect(models, ix.Measurements(image, point, col, row, 0.2))
    shuffle = np.random.default_rng(1).permutation(image.size)
    monkeypatch.setattr(ix, "CHUNK", 7)
    other = ix.intersect(
        models, ix.Measurements(image[shuffle], 1000 - 3 * point[shuffle], col[shuffle], row[shuffle], 0.2)
    )
    order = np.argsort(1000 - 3 * np.arange(50))
    np.testing.assert_array_equal(other.point, (1000 - 3 * np.arange(50))[order])
    for name in ("lon", "lat", "h", "sigma0", "rms"):
        np.testing.assert_allclose(getattr(other, name), getattr(plain, name)[order], rtol=0, atol=1e-9)
    np.testing.assert_allclose(other.covariance, plain.covariance[order], rtol=1e-9)


def test_per_measurement_sigma_weights_the_rays(scene):
    """A ray with a 100 x larger sigma hardly moves the point: the result equals the other two rays'."""
    models = scene["models"]
    truth = scene["lon"][:20], scene["lat"][:20], scene["h"][:20]
    image, point, col, row = measure(models, NAMES, *truth, noise=0.3, seed=5)
    sigma = np.where(image == "HRS2", 30.0, 0.3)
    weighted = ix.intersect(models, ix.Measurements(image, point, col, row, sigma))
    keep = image != "HRS2"
    two = ix.intersect(models, ix.Measurements(image[keep], point[keep], col[keep], row[keep], 0.3))
    assert np.abs(errors_enu(weighted, two.lon, two.lat, two.h)).max() < 0.01
    assert np.all(weighted.sigma[:, 2] < two.sigma[:, 2])


@pytest.fixture(scope="module")
def rpcs(scene):
    """RPCs fitted to the truth models over heights 0 .. 1000 m (sensors/rpc_fit.py)."""
    return {name: fit_rpc(model, (0.0, 1000.0))[0] for name, model in scene["models"].items()}


def test_rpc_models(scene, rpcs, figures):
    """The same intersection with RpcModel: exact to 1 mm on RPC-projected measurements, and within
    the fit error of the rigorous result on the same measurements (Kornus et al. 2006, Table 5)."""
    rigorous = scene["models"]
    truth = scene["lon"], scene["lat"], scene["h"]
    result = ix.intersect(rpcs, ix.Measurements(*measure(rpcs, NAMES, *truth), sigma=0.5))
    assert result.status_counts() == {"converged": N_POINTS}
    assert np.abs(errors_enu(result, *truth)).max() < 1e-3
    obs = measure(rigorous, NAMES, *truth, noise=0.3)
    a, b = (
        ix.intersect(rigorous, ix.Measurements(*obs, sigma=0.3)),
        ix.intersect(rpcs, ix.Measurements(*obs, sigma=0.3)),
    )
    dh = a.h - b.h
    figures.report("RPC - rigorous heights, RMS", np.sqrt(np.mean(dh**2)), "m")
    figures.report("RPC - rigorous heights, max", np.abs(dh).max(), "m")
    assert np.abs(errors_enu(a, b.lon, b.lat, b.h)).max() < 0.05
    np.testing.assert_allclose(b.sigma, a.sigma, rtol=0.01)


def test_pleiades_triplet_rpcs(pleiades_triplet, figures):
    """Real Pleiades RPCs: synthetic ground points (img_02 points at heights in the RPC range)
    projected into the three images are intersected to 1 mm."""
    models = {k: sensors.load(str(path)) for k, path in enumerate(pleiades_triplet, start=1)}
    rng = np.random.default_rng(2)
    cols, rows = models[2].size
    lo, hi = models[2].height_range
    c, r, h = rng.uniform(100, cols - 100, 500), rng.uniform(100, rows - 100, 500), rng.uniform(lo + 50, lo + 400, 500)
    lon, lat = models[2].image_to_ground(c, r, h)
    image, point, col, row = measure(models, (1, 2, 3), lon, lat, h)
    result = ix.intersect(models, ix.Measurements(image, point, col, row, 0.5))
    inside = np.ones(500, bool)
    for k, model in models.items():
        sel = image == k
        inside &= (col[sel] >= 0) & (col[sel] <= model.size[0]) & (row[sel] >= 0) & (row[sel] <= model.size[1])
    assert inside.sum() > 300
    assert np.all(result.ok == inside)
    assert np.all(result.status[~inside] == ix.OUTSIDE)
    err = errors_enu(result, lon, lat, h)[inside]
    assert np.abs(err).max() < 1e-3
    figures.report("median sigma E, N, H at 0.5 px", np.median(result.sigma[inside], axis=0), "m")


def test_bad_points_get_a_status(scene):
    models = scene["models"]
    truth = scene["lon"][:4], scene["lat"][:4], scene["h"][:4]
    image, point, col, row = measure(models, ("HRG", "HRS1"), *truth)
    single = (point == 1) & (image == "HRS1")
    col[(point == 2) & (image == "HRS1")] = -50.0  # outside the image
    row[(point == 3) & (image == "HRG")] = 1e7  # far beyond the ephemeris
    keep = ~single
    image, point, col, row = image[keep], point[keep], col[keep], row[keep]
    # point 4: a ray measured twice in the same image (parallel rays)
    image = np.concatenate([image, ["HRG", "HRG"]])
    point, col, row = np.r_[point, 4, 4], np.r_[col, 100.0, 100.0], np.r_[row, 200.0, 200.0]
    result = ix.intersect(models, ix.Measurements(image, point, col, row))
    assert list(result.status) == [ix.CONVERGED, ix.TOO_FEW_RAYS, ix.OUTSIDE, ix.OUTSIDE, ix.SINGULAR]
    assert np.isfinite(result.h[0]) and np.isnan(result.h[1:]).all() and np.isnan(result.covariance[1:]).all()
    assert result.status_counts() == {
        "converged": 1,
        "outside a model's domain": 2,
        "fewer than 2 rays": 1,
        "singular geometry": 1,
    }


class Patchy(sensors.SensorModel):
    """A sensor model without ground for rows beyond `row_max`: image_to_ground_or_nan gives NaN
    there (as RpcModel where its iteration fails) or `partials` gives NaN there (as SpotModel
    beyond its orbit data)."""

    def __init__(self, model, row_max, where):
        self.model, self.row_max, self.where, self.size = model, row_max, where, model.size

    def image_to_ground_or_nan(self, col, row, h):
        lon, lat = self.model.image_to_ground(col, row, h)
        if self.where == "image_to_ground":
            lon, lat = (np.where(np.asarray(row) > self.row_max, np.nan, v) for v in (lon, lat))
        return lon, lat

    def ground_to_image(self, lon, lat, h):
        return self.model.ground_to_image(lon, lat, h)

    def partials(self, lon, lat, h):
        p = dict(self.model.partials(lon, lat, h))
        if self.where == "partials":
            p["col"] = np.where(p["row"] > self.row_max, np.nan, p["col"])
        return p


@pytest.mark.parametrize("where", ["image_to_ground", "partials"])
def test_rays_outside_a_model_domain(scene, where):
    """A ray without ground point (image_to_ground fails) only changes the start: the point still
    converges to the same result; a model that cannot project the point (NaN partials) makes it
    outside the domain."""
    models = scene["models"]
    truth = scene["lon"][:40], scene["lat"][:40], scene["h"][:40]
    row = models["HRS1"].ground_to_image(*truth)[1]
    row_max = float(np.median(row))
    obs = measure(models, NAMES, *truth, noise=0.2)
    result = ix.intersect(dict(models, HRS1=Patchy(models["HRS1"], row_max, where)), ix.Measurements(*obs, sigma=0.2))
    if where == "image_to_ground":
        plain = ix.intersect(models, ix.Measurements(*obs, sigma=0.2))
        assert result.status_counts() == {"converged": 40}
        assert np.abs(errors_enu(result, plain.lon, plain.lat, plain.h)).max() < 1e-6
    else:
        assert np.all(result.status[row > row_max + 0.01] == ix.OUTSIDE)
        assert np.all(result.status[row < row_max - 0.01] == ix.CONVERGED)


def test_rpc_rays_meeting_beyond_the_height_range(scene, rpcs):
    """An RPC pair whose rays meet thousands of metres outside the RPCs' height range (0..1000 m):
    outside the models' domain."""
    truth = scene["lon"][:2], scene["lat"][:2], scene["h"][:2]
    image, point, col, row = measure(rpcs, ("HRG", "HRS1"), *truth)
    moved = (point == 1) & (image == "HRS1")
    row[moved] += np.where(row[moved] < rpcs["HRS1"].size[1] / 2, 250.0, -250.0)
    result = ix.intersect(rpcs, ix.Measurements(image, point, col, row))
    assert list(result.status) == [ix.CONVERGED, ix.OUTSIDE]


def test_bad_input_raises_clear_errors(scene):
    models = scene["models"]
    with pytest.raises(InputError, match="no sensor model for image.*XS"):
        ix.intersect(models, ix.Measurements(["HRG", "XS"], [0, 0], [1.0, 2.0], [1.0, 2.0]))
    with pytest.raises(InputError, match="one length"):
        ix.intersect(models, ix.Measurements(["HRG", "HRS1"], [0, 0, 1], [1.0, 2.0], [1.0, 2.0]))
    with pytest.raises(InputError, match="sigma"):
        ix.intersect(models, ix.Measurements(["HRG", "HRS1"], [0, 0], [1.0, 2.0], [1.0, 2.0], 0.0))
    with pytest.raises(InputError, match="finite"):
        ix.intersect(models, ix.Measurements(["HRG", "HRS1"], [0, 0], [1.0, np.nan], [1.0, 2.0]))
    empty = ix.intersect(models, ix.Measurements([], [], [], []))
    assert len(empty) == 0 and empty.status_counts() == {}


def test_cancel(scene):
    models = scene["models"]
    with pytest.raises(CancelledError):
        ix.intersect(
            models,
            ix.Measurements(*measure(models, NAMES, scene["lon"], scene["lat"], scene["h"])),
            feedback=Feedback(cancel_after=0),
        )


def test_summary_rows(scene):
    models = scene["models"]
    truth = scene["lon"][:100], scene["lat"][:100], scene["h"][:100]
    image, point, col, row = measure(models, NAMES, *truth, noise=0.1)
    keep = ~((point >= 60) & (image == "HRS2"))  # points 60..99: two rays
    result = ix.intersect(models, ix.Measurements(image[keep], point[keep], col[keep], row[keep], 0.1))
    group = np.where(result.rays == 3, 3, 1)
    rows = ix.summary_rows(result, group)
    assert [(r["group"], r["points"], r["converged"]) for r in rows] == [(1, 40, 40), (3, 60, 60)]
    assert rows[1]["sigma_h"] == pytest.approx(np.median(result.sigma[:60, 2]), rel=1.2e-4)
    assert rows[1]["sigma0"] == pytest.approx(np.median(result.sigma0[:60]), rel=1.2e-4)
    # the summaries of parts add up to the summary of the whole
    half = np.arange(len(result)) < 50
    parts = [ix.Intersection(*(getattr(result, f.name)[m] for f in dataclasses.fields(result))) for m in (half, ~half)]
    merged = ix.Summary().add(parts[0], group[half]).merge(ix.Summary().add(parts[1], group[~half]))
    assert merged.rows() == rows
    assert rows[1]["sigma_h"] < rows[0]["sigma_h"]
    table = ix.format_summary(rows).splitlines()
    assert table[0].split() == ["group", "points", "converged", "sigma_E", "sigma_N", "sigma_H", "sigma0"]
    assert float(table[2].split()[5]) == pytest.approx(rows[1]["sigma_h"], abs=5e-4)


def test_inverse_symmetric():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 3, 3))
    m = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(3)
    inverse, det = ix._inverse_symmetric(m)
    np.testing.assert_allclose(inverse, np.linalg.inv(m), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(det, np.linalg.det(m), rtol=1e-9)


@pytest.mark.slow
def test_throughput(scene, figures):
    """Hundreds of thousands of three-ray points (throughput reported, not asserted)."""
    models = scene["models"]
    rng = np.random.default_rng(4)
    n = 200_000
    cols, rows = models["HRG"].size
    h = rng.uniform(300.0, 600.0, n)
    lon, lat = models["HRG"].image_to_ground(rng.uniform(60, cols - 60, n), rng.uniform(60, rows - 60, n), h)
    obs = measure(models, NAMES, lon, lat, h, noise=0.1)
    start = time.perf_counter()
    result = ix.intersect(models, ix.Measurements(*obs, sigma=0.1))
    seconds = time.perf_counter() - start
    figures.report("three-ray points", n)
    figures.report("throughput", n / seconds, "points/s")
    assert result.status_counts() == {"converged": n}
    assert np.sqrt(np.mean((errors_enu(result, lon, lat, h) / result.sigma) ** 2)) < 1.1
