"""Three-image combinations and point groups (Kornus et al. 2006, section 3.3) on synthetic PAIR_DTYPE records,
and the issue's group-3 accuracy target on the simulated 3 km SPOT 5 triplet."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.group_summary import format_summary, summary_rows
from pushbroom.algorithms.matching.pair_geometry import local_affine
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.points import COMB_A, COMB_B, COMB_C, REFINED
from pushbroom.algorithms.matching.records import PAIR_DTYPE
from pushbroom.algorithms.matching.refinement import SUPPORT_CENTRE, SUPPORT_SIMILARITY
from pushbroom.algorithms.matching.three_combinations import Transfer, combine, new_cells, robust_sigma
from tests.helpers.matching_scene import DISCONTINUOUS, SINGLE_SURFACE

SHIFT1 = np.array([10.25, 5.5])  # image 0 -> forward image 1
SHIFT2 = np.array([-7.125, 3.0])  # image 0 -> backward image 2


def records(x1, y1, x2, y2, rho=0.9):
    r = np.zeros(len(x1), PAIR_DTYPE)
    r["x1"], r["y1"], r["x2"], r["y2"] = x1, y1, x2, y2
    r["rho"], r["semi_major"], r["semi_minor"] = rho, 0.04, 0.02
    return r


def scene(n=400, seed=0, noise=0.02):
    """a: n points; b: transfers of a[:300] of which 280 matched, plus 50 own points; c: transfers
    of the first 250 matched b transfers plus the first 20 own b points."""
    rng = np.random.default_rng(seed)
    x0 = rng.uniform(0, 1000, n).round(1) + 0.5
    y0 = rng.uniform(0, 1000, n).round(1) + 0.5
    a = records(
        x0,
        y0,
        x0 + SHIFT1[0] + rng.normal(0, noise, n),
        y0 + SHIFT1[1] + rng.normal(0, noise, n),
        rho=rng.uniform(0.6, 1.0, n),
    )
    src = np.arange(300)
    matched = src[np.arange(300) % 15 != 0]  # 280 matched of 300
    bt = records(
        a["x1"][matched] + 1e-9, a["y1"][matched], a["x1"][matched] + SHIFT2[0], a["y1"][matched] + SHIFT2[1], rho=0.8
    )  # matcher's x1 slightly off: combine must keep a's
    xo, yo = rng.uniform(2000, 3000, 50), rng.uniform(0, 1000, 50)
    bo = records(xo, yo, xo + SHIFT2[0], yo + SHIFT2[1], rho=0.75)
    b = np.concatenate([bt, bo])
    b_src = np.concatenate([matched, np.full(50, -1)])
    c_src = np.concatenate([np.arange(250), 280 + np.arange(20)])
    x2, y2 = b["x2"][c_src], b["y2"][c_src]
    c = records(
        x2,
        y2,
        x2 - SHIFT2[0] + SHIFT1[0] + rng.normal(0, noise, len(c_src)),
        y2 - SHIFT2[1] + SHIFT1[1] + rng.normal(0, noise, len(c_src)),
        rho=0.85,
    )
    return a, b, b_src, c, c_src


def test_counts_per_group():
    a, b, b_src, c, c_src = scene()
    mp = combine(a, Transfer(b, b_src), Transfer(c, c_src), image_ids=(11, 12, 13))
    # group 3: 250 (a, b, c); group 2: 30 (a, b) + 20 (b own, c); group 1: 120 (a only) + 30 (b own only)
    assert mp.stats["matched_3"] == 250
    counts = mp.group_counts()
    assert counts[1] == 150 and counts[2] == 50
    assert counts[3] == 250 - mp.stats["rejected_3sigma"]
    assert mp.stats["rejected_3sigma"] < 10  # Gaussian noise: a few beyond 3 sigma at most
    p = mp.points
    assert np.array_equal(p["id"], np.arange(1, len(p) + 1))
    assert set(p["flags"][p["group"] == 3]) == {COMB_A | COMB_B | COMB_C}
    assert set(p["flags"][p["group"] == 2]) == {COMB_A | COMB_B, COMB_B | COMB_C}
    assert set(p["flags"][p["group"] == 1]) == {COMB_A, COMB_B}
    # observations: 3 per three-ray point, 2 per two-ray point, sorted by point then image
    per_point = np.bincount(mp.observations["point_id"], minlength=len(p) + 1)[1:]
    assert np.array_equal(per_point, np.where(p["group"] == 1, 2, 3))
    key = mp.observations["point_id"] * 100 + mp.observations["image_id"]
    assert np.all(np.diff(key) > 0)
    # rho kept per combination
    g3 = p[p["group"] == 3]
    assert np.all(g3["rho_b"] == np.float32(0.8)) and np.all(g3["rho_c"] == np.float32(0.85))
    assert np.all(g3["rho_min"] == np.fmin(g3["rho_a"], 0.8))
    rows = dict(summary_rows(mp))
    assert rows["Two-ray points (group 1)"] == 150
    assert rows["Points matched in 3 combinations"] == 250
    assert "group 3" in format_summary(summary_rows(mp))


def test_transfer_points_keep_first_image_coordinates_exactly():
    a, b, b_src, c, c_src = scene()
    mp = combine(a, Transfer(b, b_src), Transfer(c, c_src), image_ids=(1, 2, 3), sigma_factor=1e9)
    p = mp.points
    col0, row0 = mp.coordinates(1)
    col2, row2 = mp.coordinates(3)
    from_a = (p["flags"] & COMB_A) > 0
    # the a points come first, in order: image 0 coordinates are a's, bit for bit
    assert np.array_equal(col0[from_a], a["x1"]) and np.array_equal(row0[from_a], a["y1"])
    # image 2 of every point in (b) is b's matched position, also where (c) used it as template
    in_b = (p["flags"] & COMB_B) > 0
    order = np.concatenate([np.argsort(b_src[b_src >= 0]), np.flatnonzero(b_src < 0)])
    assert np.array_equal(col2[in_b], b["x2"][order]) and np.array_equal(row2[in_b], b["y2"][order])
    # forward image: group 3 is the average of (a) and (c)
    col1, _ = mp.coordinates(2)
    g3 = np.flatnonzero(p["group"] == 3)
    assert np.allclose(col1[g3], (a["x2"][g3] + c["x2"][:250]) / 2)
    assert np.allclose(p["dx"][g3], (a["x2"][g3] - c["x2"][:250]) / 2)


def test_three_sigma_test_removes_inconsistent_points():
    a, b, b_src, c, c_src = scene(noise=0.05)
    bad = np.array([3, 40, 77, 150, 201])  # c records of group 3 points
    c["x2"][bad[:3]] += 2.0
    c["y2"][bad[3:]] -= 1.5
    mp = combine(a, Transfer(b, b_src), Transfer(c, c_src))
    sigma = mp.stats["sigma_dx"]
    assert 0.03 < sigma < 0.08  # robust: blunders do not inflate it
    assert mp.stats["rejected_3sigma"] >= 5
    assert mp.stats["rejected_3sigma"] <= 5 + 5  # few good ones beyond 3 sigma
    # the blundered points are gone: every kept group 3 point is consistent
    g3 = mp.points[mp.points["group"] == 3]
    assert np.all(np.abs(g3["dx"]) < 3 * mp.stats["sigma_dx"])
    assert np.all(np.abs(g3["dy"]) < 3 * mp.stats["sigma_dy"])
    assert len(mp) == 400 + 50 - mp.stats["rejected_3sigma"]
    kept_a_x1 = mp.coordinates(1)[0][(mp.points["flags"] & COMB_A) > 0]
    for k in bad:  # c[k] came from b[k], from a[matched[k]]
        assert a["x1"][b_src[c_src[k]]] not in kept_a_x1


def test_perfect_data_keep_all_group_3_points():
    a, b, b_src, c, c_src = scene(noise=0.0)
    c["x2"], c["y2"] = (
        a["x2"][b_src[c_src[:250]]].tolist() + c["x2"][250:].tolist(),
        a["y2"][b_src[c_src[:250]]].tolist() + c["y2"][250:].tolist(),
    )
    mp = combine(a, Transfer(b, b_src), Transfer(c, c_src))
    assert mp.stats["rejected_3sigma"] == 0 and mp.group_counts()[3] == 250


def test_two_images_give_group_1_only():
    a, *_ = scene()
    mp = combine(a, image_ids=(5, 7))
    assert mp.group_counts() == {1: 400, 2: 0, 3: 0}
    assert set(mp.points["flags"]) == {COMB_A}
    assert set(mp.observations["image_id"]) == {5, 7}
    assert len(mp.observations) == 800
    assert np.array_equal(mp.coordinates(5)[0], a["x1"]) and np.array_equal(mp.coordinates(7)[1], a["y2"])
    assert mp.stats["images"] == [5, 7]
    assert np.all(np.isnan(mp.observations["rho"][mp.observations["image_id"] == 5]))


def test_empty_and_bad_links():
    mp = combine(np.zeros(0, PAIR_DTYPE), Transfer(np.zeros(0, PAIR_DTYPE), []), Transfer(np.zeros(0, PAIR_DTYPE), []))
    assert len(mp) == 0 and len(mp.observations) == 0
    a = scene()[0][:10]
    with pytest.raises(InputError):
        combine(a, Transfer(a[:2], [0, 99]))
    with pytest.raises(InputError):
        combine(a, Transfer(a[:2], [0]))


def test_helpers():
    assert robust_sigma([], 0.5) == 0.5
    assert robust_sigma([1.0, -1.0, 1.0], 0.0) == pytest.approx(1.4826)
    mask = new_cells([5, 15, 25], [5, 5, 5], [1, 22], [1, 9], 10)
    assert mask.tolist() == [False, True, False]


def test_guide_for_combination_c_composes_the_affines():
    from pushbroom.algorithms.matching.three_combinations import compose_guide

    a, b, b_src, _, _ = scene()
    a["a1"], a["a2"], a["a4"], a["a5"] = 1.2, 0.1, 0.0, 1.0  # image 0 -> 1
    b["a1"], b["a2"], b["a4"], b["a5"] = 0.8, 0.0, 0.05, 1.0  # image 0 -> 2
    b["a1"][0] = b["a2"][0] = 0.0  # singular: left out
    g = compose_guide(a, b, b_src)
    assert len(g) == 279
    src = b_src[1:280]
    assert np.array_equal(g["x1"], b["x2"][1:280]) and np.array_equal(g["x2"], a["x2"][src])
    C = np.array([[1.2, 0.1], [0.0, 1.0]]) @ np.linalg.inv(np.array([[0.8, 0.0], [0.05, 1.0]]))
    assert np.allclose([g["a1"][0], g["a2"][0], g["a4"][0], g["a5"][0]], C.ravel(), atol=1e-6)


# ------------------------------------------------------------------------------------------
# the target on the simulated triplet: GROUP-3 points of match_block (HRG, HRS1, HRS2)


@pytest.fixture(scope="module")
def triplet(small_matching_scene, small_scene_matched):
    """match_block on the 3 km triplet (supplied, perturbed models), with and without the MPGC
    refinement; per group-3 point of the refined run: class and the errors of its HRS1 and HRS2
    positions against the point truth and the template-area truth (matching_scene) of its HRG
    position; for both runs the errors against the point truth."""
    scene = small_matching_scene
    models = [sensors.load(scene.paths["images"][k]["metadata"]) for k in ("HRG", "HRS1", "HRS2")]
    mp = small_scene_matched(GrowParams())
    plain = small_scene_matched(GrowParams(), refine=False)
    supported = small_scene_matched(GrowParams(support_weights=True))
    out = {"points": mp, "plain": plain}
    for run, points, support in (("", mp, (0.0, 0.0)), (" support", supported, (SUPPORT_CENTRE, SUPPORT_SIMILARITY))):
        g3 = points.points["group"] == 3
        x0, y0 = (v[g3] for v in points.coordinates(1))
        out["n" + run], out["stats" + run] = int(g3.sum()), points.stats
        for image_id, name, model in ((2, "HRS1", models[1]), (3, "HRS2", models[2])):
            x, y = (v[g3] for v in points.coordinates(image_id))
            truth = scene.truth_model(name)
            tx, ty, cls = scene.truth(x0, y0, truth)
            rec = np.zeros(len(x0), PAIR_DTYPE)
            rec["x1"], rec["y1"] = x0, y0
            _, _, *aff = local_affine(models[0], model, x0, y0, 0.5 * sum(scene.height_range))
            for field, value in zip(("a1", "a2", "a4", "a5"), aff):
                rec[field] = value
            ax, ay = scene.area_truth(rec, model2=truth, support=support)
            out[name + run] = (np.hypot(x - tx, y - ty), np.hypot(x - ax, y - ay))
            out["class" + run] = cls
            if not run:
                px, py = (v[g3] for v in plain.coordinates(image_id))
                out[name + " plain"] = np.hypot(px - tx, py - ty)
    return out


@pytest.mark.ratchet
def test_group3_accuracy_on_the_simulated_triplet(triplet, figures):
    """Issue target: group-3 points on textured classes, RMS < 0.15 px and < 0.5 % beyond 1 px.
    Bare fields and crops (one surface inside the template) are held to the pointwise truth;
    forest and city (height steps inside the template) to the template-area truth; the MPGC refinement
    (refinement.py, the default) is what meets the target (docs/validation.md#group3-accuracy)."""
    cls = triplet["class"]
    single, steps = np.isin(cls, SINGLE_SURFACE), np.isin(cls, DISCONTINUOUS)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))
    figures.report("group-3 points", triplet["n"])
    figures.report("matching statistics", triplet["stats"])
    for name in ("HRS1", "HRS2"):
        point, area = triplet[name]
        figures.table(
            f"{name} per class (px)",
            [
                {
                    "class": label,
                    "n": (cls == c).sum(),
                    "RMS": rms(point[cls == c]),
                    "RMS vs the area truth": rms(area[cls == c]),
                    "> 1 px %": 100 * np.mean(point[cls == c] > 1),
                }
                for c, label in {2: "bare", 3: "crops", 4: "forest", 5: "city"}.items()
            ],
        )
        figures.report(f"{name} fields RMS", rms(point[single]), "px")
        figures.report(f"{name} fields RMS vs the area truth", rms(area[single]), "px")
        figures.report(f"{name} fields RMS without the refinement", rms(triplet[name + " plain"][single]), "px")
        figures.report(f"{name} forest+city RMS vs the area truth", rms(area[steps]), "px")
    assert triplet["n"] > 800 and triplet["stats"]["refined_mpgc"] > 0.95 * triplet["n"]
    for name in ("HRS1", "HRS2"):
        point, area = triplet[name]
        assert rms(point[single]) < 0.15 < rms(triplet[name + " plain"][single])
        assert np.mean(point[single] > 1.0) < 0.005
        assert rms(area[steps]) < 0.15
        assert np.mean(area[steps] > 1.0) < 0.005


@pytest.mark.ratchet
def test_group3_with_support_weights(triplet, figures):
    """GrowParams.support_weights (the DEM pipeline's setting; refinement.py): the MPGC windows weighted
    towards the template centre and its own surface. Fields closer to the point truth than with uniform
    windows; forest and city held to the template-area truth with the same weights
    (docs/validation.md#group3-accuracy)."""
    cls = triplet["class support"]
    single, steps = np.isin(cls, SINGLE_SURFACE), np.isin(cls, DISCONTINUOUS)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))
    assert triplet["n support"] > 800 and triplet["stats support"]["refined_mpgc"] > 0.95 * triplet["n support"]
    uniform_fields = np.isin(triplet["class"], SINGLE_SURFACE)
    for name in ("HRS1", "HRS2"):
        point, area = triplet[name + " support"]
        uniform = rms(triplet[name][0][uniform_fields])
        figures.report(f"{name} fields RMS", rms(point[single]), "px")
        figures.report(f"{name} fields RMS vs the area truth", rms(area[single]), "px")
        figures.report(f"{name} fields RMS with uniform windows", uniform, "px")
        figures.report(f"{name} forest+city RMS vs the area truth", rms(area[steps]), "px")
        assert rms(point[single]) < uniform
        assert np.mean(point[single] > 1.0) < 0.005
        assert rms(area[steps]) < 0.15 and np.mean(area[steps] > 1.0) < 0.005


def test_refinement_keeps_the_reference_and_the_other_points(triplet):
    """The MPGC refinement moves only the search positions of group 3 points it accepts (flag
    REFINED): reference positions, groups and every other observation are those of the run
    without it."""
    mp, plain = triplet["points"], triplet["plain"]
    np.testing.assert_array_equal(mp.points["id"], plain.points["id"])
    np.testing.assert_array_equal(mp.points["group"], plain.points["group"])
    refined = (mp.points["flags"] & REFINED) > 0
    assert refined.sum() == triplet["stats"]["refined_mpgc"] and np.all(mp.points["group"][refined] == 3)
    np.testing.assert_array_equal(mp.points["flags"] & ~np.uint8(REFINED), plain.points["flags"])
    np.testing.assert_array_equal(mp.coordinates(1)[0], plain.coordinates(1)[0])
    np.testing.assert_array_equal(mp.coordinates(1)[1], plain.coordinates(1)[1])
    moved = np.zeros(len(mp), bool)
    for image_id in (2, 3):
        a, b = np.array(mp.coordinates(image_id)), np.array(plain.coordinates(image_id))
        same = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=0)
        assert np.all(same[~refined])
        moved |= ~same
    assert moved[refined].mean() > 0.99
    bias = np.array(triplet["stats"]["refine_bias_px"])
    assert bias.shape == (2, 6) and np.all(np.abs(bias[:, 2:]) < 1e-3)  # the 3 km scene: a shift
    assert triplet["stats"]["refine_sigma_geometry_px"] == 0.05
    rows = dict(summary_rows(mp))
    assert rows["Group 3 points refined by MPGC"] == refined.sum() and "Group 3 points refined by MPGC" not in dict(
        summary_rows(plain)
    )
