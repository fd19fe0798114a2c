"""MPGC refinement's orientation correction (algorithms/matching/refinement.py): the affine
image bias against injected biases on the simulated triplet's truth models, and the affine
ShiftedModel against finite differences. Its effect on the group 3 points is asserted in
test_three_combinations.py."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching.coarse_to_fine_level import ShiftedModel
from pushbroom.algorithms.matching.refinement import affine_bias

NAMES = ("HRG", "HRS1", "HRS2")


@pytest.fixture(scope="module")
def rays(small_scene):
    """Truth models and the true positions of 2000 ground points seen by all three images."""
    truths = [sensors.load(small_scene["truth_metadata"][k]) for k in NAMES]
    dsm = read_dem(small_scene["dsm"])
    rng = np.random.default_rng(5)
    cols, rows = truths[0].size
    x0, y0 = rng.uniform(100, cols - 100, 2000), rng.uniform(100, rows - 100, 2000)
    lon, lat, h = truths[0].image_to_dem(x0, y0, dsm)
    pos = np.array([np.array(m.ground_to_image(lon, lat, h), float) for m in truths])  # (3, 2, m)
    return truths, pos


def test_shifted_model_with_a_linear_part(rays):
    """(col', row') = M (col, row) + d: inverse and partials (against central differences)."""
    model = rays[0][1]
    moved = ShiftedModel(model, 3.0, -2.0, linear=[[1.001, 2e-4], [-3e-4, 0.9995]])
    lon, lat = model.image_to_ground(np.array([400.0, 1200.0]), np.array([300.0, 900.0]), np.array([500.0, 700.0]))
    h = np.array([500.0, 700.0])
    x, y = moved.ground_to_image(lon, lat, h)
    x0, y0 = model.ground_to_image(lon, lat, h)
    np.testing.assert_allclose(x, 1.001 * x0 + 2e-4 * y0 + 3.0, atol=1e-9)
    np.testing.assert_allclose(y, -3e-4 * x0 + 0.9995 * y0 - 2.0, atol=1e-9)
    lon2, lat2 = moved.image_to_ground(x, y, h)
    np.testing.assert_allclose(np.c_[lon2, lat2], np.c_[lon, lat], atol=1e-10)
    part = moved.partials(lon, lat, h)
    np.testing.assert_allclose(part["col"], x, atol=1e-9)
    np.testing.assert_allclose(part["row"], y, atol=1e-9)
    for j, d in enumerate((1e-6, 1e-6, 1.0)):
        step = [np.zeros(2), np.zeros(2), np.zeros(2)]
        step[j] += d
        xp, yp = moved.ground_to_image(lon + step[0], lat + step[1], h + step[2])
        xm, ym = moved.ground_to_image(lon - step[0], lat - step[1], h - step[2])
        np.testing.assert_allclose(part["d_ground"][:, 0, j], (xp - xm) / (2 * d), rtol=1e-5)
        np.testing.assert_allclose(part["d_ground"][:, 1, j], (yp - ym) / (2 * d), rtol=1e-5)


def biased(pos, noise, reference=False, seed=7):
    """The true positions with the injected affine maps of the search images (and, with
    `reference`, a shift and rotation of the reference image), noise and 1 % gross errors of 3-8 px
    in image 1: (observed positions, maps, indices of the gross errors)."""
    rng = np.random.default_rng(seed)
    m = pos.shape[2]
    observed = pos.copy()
    maps = [
        ([[1 + 2e-4, -1e-4], [1.5e-4, 1 - 1e-4]], [4.2, -3.1]),
        ([[1 - 1e-4, 2e-4], [-1e-4, 1 + 2e-4]], [-2.5, 5.0]),
    ]
    for i, (lin, d) in enumerate(maps, start=1):
        observed[i] = np.asarray(lin) @ pos[i] + np.asarray(d)[:, None]
    if reference:
        observed[0] = np.array([[1.0, 3e-4], [-3e-4, 1.0]]) @ pos[0] + np.array([[1.5], [-2.0]])
    observed += rng.normal(0.0, noise, observed.shape)
    gross = rng.choice(m, m // 100, replace=False)
    observed[1, 1, gross] += rng.uniform(3, 8, gross.size) * rng.choice([-1, 1], gross.size)
    return observed, maps, gross


def ray_rms(corrected, inter, observed, clean):
    """RMS (px) per image of the clean points' positions against the corrected models' projections
    of their intersections."""
    return [
        float(
            np.sqrt(
                np.mean(
                    np.square(
                        np.hypot(
                            *(
                                observed[i][:, clean]
                                - np.array(corrected[i].ground_to_image(inter.lon, inter.lat, inter.h))[:, clean]
                            )
                        )
                    )
                )
            )
        )
        for i in range(3)
    ]


@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_affine_bias_removes_injected_biases(rays, noise, figures):
    """Affine biases injected into the search images' true positions (up to 5 px shift and 2e-4
    rotation and scale, the supplied models' size; 1 % gross errors of 3-8 px): the corrected
    models' rays meet again (residual RMS of the clean points at the noise level) and the
    tile-median consistency is below 0.01 px plus the noise of a median of ~125 points (0.11 x
    noise); the corrections equal the injected maps up to what
    the rays cannot see (columns to 0.01 px + noise / 5: 2000 points)."""
    truths, pos = rays
    observed, maps, gross = biased(pos, noise)
    corrected, inter, systematic = affine_bias(truths, observed[:, 0], observed[:, 1])
    rms = ray_rms(corrected, inter, observed, np.setdiff1d(np.arange(pos.shape[2]), gross))
    figures.report("ray residual RMS", rms, "px")
    figures.report("systematic", systematic, "px")
    assert max(rms) < 0.01 + noise and systematic < 0.01 + 0.15 * noise
    for i, (lin, d) in enumerate(maps, start=1):
        # the rays cannot see a common along-track shift: compare the maps' columns at the points
        got = corrected[i].linear[0] @ pos[i] + corrected[i].dx
        want = np.asarray(lin[0]) @ pos[i] + d[0]
        figures.report(f"{NAMES[i]}: column map vs the injected one, RMS", np.sqrt(np.mean((got - want) ** 2)), "px")
        assert np.sqrt(np.mean((got - want) ** 2)) < 0.01 + 0.2 * noise


def test_affine_bias_moves_a_reference_bias_to_the_search_images(rays, figures):
    """A shift and rotation of the reference image too (its model is held): the reference's
    residual is moved into the search images' maps, and the rays meet as without it; without that
    move (the reference residual left in the fit) they would not."""
    truths, pos = rays
    observed, _, gross = biased(pos, 0.0, reference=True)
    corrected, inter, systematic = affine_bias(truths, observed[:, 0], observed[:, 1])
    clean = np.setdiff1d(np.arange(pos.shape[2]), gross)
    rms = ray_rms(corrected, inter, observed, clean)
    figures.report("ray residual RMS", rms, "px")
    figures.report("systematic", systematic, "px")
    assert max(rms) < 0.02 and systematic < 0.01
    plain = affine_bias(truths, observed[:, 0], observed[:, 1], iterations=0)
    assert max(ray_rms(*plain[:2], observed, clean)) > 0.5


def test_consistency_measures_what_an_affine_map_cannot_fit(rays, figures):
    """A quadratic distortion across the forward image (0.3 px at its edges) is beyond the affine
    maps: the tile-median consistency rises well above the affine case's, so the refinement's
    sigma_geometry (2 x it, at least 0.05 px) loosens; with too few points per tile it is NaN."""
    truths, pos = rays
    observed, _, _ = biased(pos, 0.0)
    half = 0.5 * truths[1].size[0]
    observed[1, 0] += 0.3 * ((pos[1, 0] - half) / half) ** 2
    systematic = affine_bias(truths, observed[:, 0], observed[:, 1])[2]
    figures.report("systematic with a quadratic 0.3 px", systematic, "px")
    assert systematic > 0.02
    assert np.isnan(affine_bias(truths, observed[:, 0, :30], observed[:, 1, :30])[2])
