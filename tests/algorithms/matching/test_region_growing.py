"""Region-growing LSM (algorithms/matching/region_growing.py): numba core against a plain-Python
reference, accuracy/coverage on a simulated SPOT 5 scene against the truth, determinism over
workers and tiles, and bad input."""

import heapq
import time

import numpy as np
import pytest

from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.matching.imagery import Image, Smoothed, Window
from pushbroom.algorithms.matching.lsm import LSM_OUT, Solver, Start, lsm_point
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing import Lattice, match_pair, transfer_points
from pushbroom.algorithms.matching.region_growing_kernels import _DC, _DR, Accept, Tile, _quantise, grow_kernel
from pushbroom.algorithms.matching.resolution import adapt_resolution
from tests.helpers.feedback import Feedback
from tests.helpers.matching_scene import DISCONTINUOUS, LOW_CONTRAST_DN, SINGLE_SURFACE


def grow_reference(tile, seeds, solve, wide, accept, results, state, origin, prior):
    """Plain-Python reference of region_growing_kernels.grow_kernel (heapq; same arguments and outputs)."""
    heap = []
    out = np.empty(results.shape[1])
    tries = 0

    img1, img2, ox1, oy1, ox2, oy2, gx0, gy0, step, nx, ny = tile

    def attempt(node, x2, y2, a1, a2, a4, a5):
        x1 = gx0 + (node % nx) * step - ox1
        y1 = gy0 + (node // nx) * step - oy1

        def criteria(status):
            return bool(
                status == 0
                and out[2] > accept.rho_min
                and out[3] < accept.max_ellipse
                and out[5] < accept.max_shift
                and out[6] < accept.max_iter
            )

        start = Start(x2 - ox2, y2 - oy2, a1, a2, a4, a5)
        status = lsm_point(img1, img2, x1, y1, start, solve, out)
        ok = criteria(status)
        if not ok and status != 1 and wide.half > solve.half:  # failed inside the images: the wide window
            status = lsm_point(img1, img2, x1, y1, start, wide, out)
            ok = criteria(status)
            out[3:5] *= (2 * wide.half + 1) / (2 * solve.half + 1)  # the ellipse in the template's units
        results[node] = out
        results[node, 0] += ox2
        results[node, 1] += oy2
        state[node] = 1 if ok else 2
        return ok

    for s in seeds:
        node = int(s[0])
        if not 0 <= node < nx * ny or state[node]:
            continue
        tries += 1
        if attempt(node, *s[1:7]):
            origin[node] = int(s[7])
            heapq.heappush(heap, (-_quantise(results[node, 2]), node))
    while heap:
        _, node = heapq.heappop(heap)
        r, c = divmod(node, nx)
        for dc, dr in zip(_DC, _DR):
            if not (0 <= c + dc < nx and 0 <= r + dr < ny):
                continue
            nb = (r + dr) * nx + c + dc
            if state[nb]:
                continue
            a1, a2, a4, a5 = results[node, 7:11] if len(prior) != 4 else prior
            dk, dl = dc * step, dr * step
            tries += 1
            if attempt(nb, results[node, 0] + a1 * dk + a2 * dl, results[node, 1] + a4 * dk + a5 * dl, a1, a2, a4, a5):
                origin[nb] = origin[node]
                heapq.heappush(heap, (-_quantise(results[nb, 2]), nb))
    return tries


# --------------------------------------------------------------------------------------------
# lattice and tiles


def texture(shape, seed):
    """Smooth random texture (sum of blurred noise), float32."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    return (100 + 400 * gaussian_filter(rng.standard_normal(shape), 1.5)).astype(np.float32)


def kernel_case(prior, whalf, contrast=1.0, noise=0.0):
    """Tiny synthetic case: image 2 = image 1 shifted by (2.3, -1.6) px with a flat patch where
    growth must stop; `contrast` < 1 weakens the texture of the left half against the `noise` (DN),
    so that some 9 x 9 windows fail the error ellipse. Runs the numba core and the heapq reference."""
    from scipy.ndimage import shift as nd_shift

    img1 = texture((90, 90), 3)
    img1[:, :45] = 100 + contrast * (img1[:, :45] - 100)
    img2 = nd_shift(img1.astype(float), (-1.6, 2.3), order=3, mode="nearest").astype(np.float32)
    img2[50:, 55:] = 100.0
    rng = np.random.default_rng(11)
    img1 = img1 + rng.normal(0.0, noise, img1.shape).astype(np.float32)
    img2 = img2 + rng.normal(0.0, noise, img2.shape).astype(np.float32)
    half, step, nx, ny = 4, 5, 14, 14
    seeds = np.array(
        [
            [0 * nx + 0, 7.5 + 2.3 + 0.4, 7.5 - 1.6 - 0.3, 1, 0, 0, 1, 7],
            [3 * nx + 9, 52.5 + 2.3, 22.5 - 1.6, 1, 0, 0, 1, 8],
        ],
        float,
    )
    outs = []
    for fn in (grow_kernel, grow_reference):
        results = np.full((nx * ny, LSM_OUT), np.nan)
        state = np.zeros(nx * ny, np.int8)
        origin = np.full(nx * ny, -1, np.int64)
        tile = Tile(img1, img2, 0.0, 0.0, 0.0, 0.0, 7.5, 7.5, float(step), nx, ny)
        solve, wide = Solver(half, 10, 0.01, 0.0), Solver(whalf, 10, 0.01, 0.0)
        tries = fn(tile, seeds, solve, wide, Accept(0.6, 0.1, 2.5, 10), results, state, origin, prior)
        outs.append((results, state, origin, tries))
    return outs, nx, step


@pytest.mark.parametrize("prior", [np.zeros(0), np.array([1.0, 0.0, 0.0, 1.0])], ids=["own-affine", "model-affine"])
def test_kernel_matches_python_reference(prior):
    """The numba core and the heapq reference give the same accepted set and results; growth
    covers the texture and stops at the flat patch."""
    outs, nx, step = kernel_case(prior, 0)
    (r1, s1, o1, t1), (r2, s2, o2, t2) = outs
    assert t1 == t2
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_allclose(r1, r2, rtol=1e-9, atol=1e-9, equal_nan=True)
    ok = s1 == 1
    assert 100 < ok.sum() < nx * nx  # grew over the texture, stopped at the flat patch
    np.testing.assert_allclose(r1[ok, 0] - (7.5 + step * (np.flatnonzero(ok) % nx)), 2.3, atol=0.05)
    np.testing.assert_allclose(r1[ok, 1] - (7.5 + step * (np.flatnonzero(ok) // nx)), -1.6, atol=0.05)
    assert set(o1[ok]) <= {7, 8}


@pytest.mark.ratchet
def test_wide_window_where_the_narrow_one_fails(figures):
    """Weak texture on the left: 9 x 9 windows fail the 0.1 px ellipse there; with the 15 x 15
    second window the numba core and the reference agree, more nodes are accepted (a superset),
    every accepted one within the ellipse it measured (the wide window's reported in the template's units,
    15 / 9 times; docs/validation.md#region-growing-wide-template)."""
    narrow, nx, step = kernel_case(np.zeros(0), 0, contrast=0.16, noise=4.0)
    wide, _, _ = kernel_case(np.zeros(0), 7, contrast=0.16, noise=4.0)
    (r1, s1, o1, t1), (r2, s2, o2, t2) = wide
    assert t1 == t2
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_allclose(r1, r2, rtol=1e-9, atol=1e-9, equal_nan=True)
    before, after = narrow[0][1] == 1, s1 == 1
    nodes = np.flatnonzero(after)
    error = np.hypot(
        r1[after, 0] - (7.5 + step * (nodes % nx)) - 2.3, r1[after, 1] - (7.5 + step * (nodes // nx)) + 1.6
    )
    figures.report("accepted nodes with the 9 x 9 window alone", before.sum())
    figures.report("accepted nodes with the 15 x 15 second window", after.sum())
    figures.report("error RMS", rms(error), "px")
    figures.report("error max", error.max(), "px")
    assert after.sum() > before.sum() + 10 and np.all(after[before])
    assert np.all(r1[before, 3] < 0.1) and np.all(r1[after & ~before, 3] < 0.1 * 15 / 9)
    assert np.any(r1[after & ~before, 3] >= 0.1)
    assert rms(error) < 0.15 and error.max() < 0.5


def test_lattice_is_global_and_tiles_partition_it():
    params = GrowParams(template=19, step=10, tile=64)
    lattice = Lattice((600, 599), params)
    owned = np.zeros((lattice.nrows, lattice.ncols), int)
    for n_a, n_b, m_a, m_b in lattice.tiles(64):
        owned[m_a:m_b, n_a:n_b] += 1
    assert (owned == 1).all()
    x, y = lattice.position(0, lattice.ncols - 1)
    assert x == 9.5 + 10 * (lattice.ncols - 1) and x + 9 <= 599.5 and y == 9.5


# ------------------------------------------------------------------------------------------
# simulated scene


@pytest.fixture(scope="module")
def scene(small_matching_scene):
    return small_matching_scene


@pytest.fixture(scope="module")
def grown(scene):
    match_pair(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams(tile=256), scene.height_range
    )  # compile outside the timing
    feedback = Feedback()
    start = time.perf_counter()
    records = match_pair(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        GrowParams(),
        scene.height_range,
        feedback=feedback,
    )
    seconds = time.perf_counter() - start
    x2, y2, cls = scene.truth(records["x1"], records["y1"])
    error = np.hypot(records["x2"] - x2, records["y2"] - y2)
    ax2, ay2 = scene.area_truth(records)
    area_error = np.hypot(records["x2"] - ax2, records["y2"] - ay2)
    return records, error, area_error, cls, seconds, feedback


@pytest.fixture(scope="module")
def nodes(scene, simulated):
    """Lattice nodes whose template lies inside image 2: class, ground texture, and the best
    precision LSM can reach there (Scene.matchable_precision, from the same scene simulated
    without noise)."""
    from pushbroom.algorithms.simulation import SceneConfig

    quiet = simulated(SceneConfig.small(noise=0.0))
    x1, y1, cls = scene.lattice_nodes()
    return x1, y1, cls, scene.texture(x1, y1), scene.matchable_precision(x1, y1, quiet)


def rms(e):
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def test_smoothed_window_equals_whole_image_filter():
    """A Smoothed window is the crop of the whole filtered image (borders included)."""
    from scipy.ndimage import gaussian_filter

    img = texture((70, 90), 5)
    full = gaussian_filter(img, (0.3, 0.8), mode="nearest", truncate=4.0)
    view = Smoothed(Image(img), 0.8, 0.3)
    for x0, y0, cols, rows in ((10, 12, 30, 20), (-5, -3, 25, 30), (70, 50, 40, 40)):
        win, xa, ya = view.read(x0, y0, cols, rows)
        ref, xr, yr = Image(full).read(x0, y0, cols, rows)
        assert (xa, ya) == (xr, yr)
        np.testing.assert_allclose(win, ref, rtol=1e-5, atol=1e-3)


def test_window_reads_are_the_image_crop():
    """A Window reads its image's pixels in its own coordinates, clipped to the window (also where
    the window of a Smoothed image lies at its border)."""
    img = texture((70, 90), 6)
    win = Window(Image(img), 20, 10, 40, 30)
    data, xa, ya = win.read(-5, 3, 50, 10)
    assert (xa, ya) == (0, 3) and data.shape == (10, 40)
    np.testing.assert_array_equal(data, img[13:23, 20:60])
    assert win.read(45, 0, 5, 5)[0].size == 0
    smooth = Smoothed(Image(img), 0.8, 0.8)
    data, xa, ya = Window(smooth, 50, 40, 40, 30).read(0, 0, 40, 30)
    np.testing.assert_array_equal(data, smooth.read(50, 40, 40, 30)[0])


def test_adapt_resolution_low_passes_the_finer_image(scene):
    """HRG (5 m) -> HRS1 (10 m detectors, 5 m lines), psf "sensor" (default): PSF variances in own
    px, across 1/12 + 0.4^2 = 0.243 for both, along 3/12 + 0.16 = 0.327 (HRG) and 4/12 + 1/12 +
    0.8^2 = 1.057 lines^2 (HRS); a1 ~ 0.53, a5 ~ 1, so HRG is low-passed by sqrt(0.243 / a1^2 -
    0.243) ~ 0.79 px across and sqrt(1.057 - 0.327) ~ 0.85 px along; HRS1 is untouched; swapped,
    HRS1 stays and HRG (now image 2) is low-passed. psf "pixel" (square detectors of psf_sigma
    0.5 px): 0.81 / 0.8 px. psf "off" or "pixel" with psf_sigma 0 turns it off; a model without an
    instrument (RPC) falls back to "pixel"."""
    from pushbroom.algorithms.matching.resolution import sensor_psf

    args = (Image(str(scene.image1)), Image(str(scene.image2)))
    hr = scene.height_range
    assert np.allclose(np.diag(sensor_psf(scene.model2)), [1 / 12 + 0.16, 5 / 12 + 0.64])
    i1, i2 = adapt_resolution(*args, scene.model1, scene.model2, GrowParams(), hr)
    assert isinstance(i1, Smoothed) and isinstance(i2, Image)
    assert i1.sigma[1] == pytest.approx(0.79, abs=0.02) and i1.sigma[0] == pytest.approx(0.855, abs=0.02)
    j2, j1 = adapt_resolution(args[1], args[0], scene.model2, scene.model1, GrowParams(), hr)
    assert isinstance(j2, Image) and isinstance(j1, Smoothed)
    assert j1.sigma[1] == pytest.approx(0.79, abs=0.02) and j1.sigma[0] > 0.7
    k1, k2 = adapt_resolution(*args, scene.model1, scene.model2, GrowParams(psf="pixel"), hr)
    assert isinstance(k2, Image)
    assert k1.sigma[1] == pytest.approx(0.81, abs=0.03) and k1.sigma[0] == pytest.approx(0.81, abs=0.05)

    class NoInstrument:  # as an RPC model: no orientation
        size = scene.model2.size

        def __init__(self, model):
            self.model = model

        def image_to_ground(self, *a):
            return self.model.image_to_ground(*a)

        def ground_to_image(self, *a):
            return self.model.ground_to_image(*a)

    assert sensor_psf(NoInstrument(scene.model2)) is None
    f1, _ = adapt_resolution(*args, scene.model1, NoInstrument(scene.model2), GrowParams(), hr)
    assert f1.sigma == k1.sigma
    assert adapt_resolution(*args, scene.model1, scene.model2, GrowParams(psf="off"), hr) == args
    assert adapt_resolution(*args, scene.model1, scene.model2, GrowParams(psf="pixel", psf_sigma=0.0), hr) == args
    with pytest.raises(InputError, match="psf must be"):
        GrowParams(psf="gauss").check()


@pytest.mark.slow
@pytest.mark.ratchet
def test_region_growing_accuracy_against_truth(grown, figures):
    """Pairwise region growing HRG -> HRS1 (combination (a) alone). The issue's targets, RMS < 0.15
    px and < 0.5 % errors > 1 px on textured classes, are for the group-3 points, which the MPGC
    refinement brings below it (test_three_combinations.py). Forest and city are dominated by height steps inside
    the template and are held to the template-area truth instead (docs/validation.md#region-growing-accuracy)."""
    records, error, area_error, cls, seconds, feedback = grown
    single = np.isin(cls, SINGLE_SURFACE)
    steps = np.isin(cls, DISCONTINUOUS)
    names = {2: "bare", 3: "crops", 4: "forest", 5: "city"}
    figures.report("points", len(records))
    figures.report("matching", seconds, "s", f"{len(records) / seconds:.0f} points/s")
    figures.table(
        "per class (px)",
        [
            {
                "class": name,
                "n": (cls == c).sum(),
                "RMS": rms(error[cls == c]),
                "RMS vs the template-area truth": rms(area_error[cls == c]),
                "> 1 px %": 100 * np.mean(error[cls == c] > 1),
            }
            for c, name in names.items()
        ],
    )
    assert len(records) > 1000
    assert rms(error[single]) < 0.21  # docs/validation.md#region-growing-accuracy
    assert np.mean(error[single] > 1.0) < 0.005  # target met
    assert rms(area_error[steps]) < 0.15 and np.mean(area_error[steps] > 1.0) < 0.005
    assert np.all(records["rho"] > 0.6) and np.all(records["semi_major"] < 0.1)
    assert any("points accepted" in m for m in feedback.messages)


#: px: the 0.1 px acceptance in terms of true precision on the resolution-adapted HRG -> HRS pair,
#: whose LSM ellipse is 1.33x optimistic (studies/adapted_lsm_calibration.py)
EFFECTIVE_ELLIPSE = 0.133


def coverage(records, error, nodes, figures, label):
    """Report (`figures`, headed `label`) and return (share of textured nodes covered, share of
    low-texture nodes covered, the errors of the points on low-texture nodes, share of matchable nodes
    covered: those whose texture and noise allow the acceptance's error ellipse, noise-only precision
    < 0.1 px)."""
    x1, y1, cls, texture, bound = nodes
    key = np.rint(x1 * 2) + 1e5 * np.rint(y1 * 2)
    rkey = np.rint(records["x1"] * 2) + 1e5 * np.rint(records["y1"] * 2)
    hit = np.isin(key, rkey)
    textured = texture >= LOW_CONTRAST_DN
    low = (cls == 3) & ~textured
    on_low = error[np.isin(rkey, key[low])]
    matchable = bound < GrowParams().max_ellipse
    figures.table(
        f"{label}: nodes covered per class (%)",
        [
            {
                "class": name,
                "textured nodes": ((cls == c) & textured).sum(),
                "covered": 100 * hit[(cls == c) & textured].mean(),
                "matchable covered": 100 * hit[matchable & (cls == c)].mean(),
            }
            for c, name in {2: "bare", 3: "crops", 4: "forest", 5: "city"}.items()
        ],
    )
    figures.report(f"{label}: textured nodes covered", 100 * hit[textured].mean(), "%")
    figures.report(f"{label}: uniform grass parcel nodes covered", 100 * hit[low].mean(), "%")
    figures.report(
        f"{label}: points on uniform grass parcels, RMS", rms(on_low), "px", f"> 1 px {100 * np.mean(on_low > 1):.2f} %"
    )
    figures.report(
        f"{label}: matchable nodes (noise-only precision < {GrowParams().max_ellipse} px)",
        matchable.sum(),
        note=f"{100 * matchable[textured].mean():.1f} % of the textured ones; "
        f"{(textured & ~matchable).sum()} textured ones not",
    )
    figures.report(f"{label}: matchable nodes covered", 100 * hit[matchable].mean(), "%")
    on_fields = np.isin(rkey, key[np.isin(cls, SINGLE_SURFACE)])
    on_matchable = np.isin(rkey, key[matchable])
    effective = bound < EFFECTIVE_ELLIPSE
    figures.report(
        f"{label}: nodes with noise-only precision < {EFFECTIVE_ELLIPSE} px",
        effective.sum(),
        note=f"covered {100 * hit[effective].mean():.1f} %",
    )
    figures.report(f"{label}: field points on matchable nodes, RMS", rms(error[on_fields & on_matchable]), "px")
    figures.report(f"{label}: field points on the other nodes, RMS", rms(error[on_fields & ~on_matchable]), "px")
    return hit[textured].mean(), hit[low].mean(), on_low, hit[matchable].mean()


@pytest.mark.slow
@pytest.mark.ratchet
def test_region_growing_coverage(grown, nodes, figures):
    """Coverage of lattice nodes. Bare fields are textured in the simulator; the low-texture ground of
    the 3 km scene (no water in it) is the uniform grass parcels: crop nodes whose ground DN std over the
    template is < LOW_CONTRAST_DN. The 0.1 px ellipse is the binding criterion: the textured nodes left
    empty are mostly striped crop parcels, and many textured nodes cannot reach that precision at all
    (LSM's noise-only precision from the noise-free images, Scene.matchable_precision), so coverage is
    also measured on the nodes where it can (docs/validation.md#region-growing-coverage)."""
    textured, low, _, matchable = coverage(grown[0], grown[1], nodes, figures, "default")
    assert textured > 0.68  # 70.8 % measured: 43 % of these nodes cannot reach the 0.1 px ellipse
    assert matchable > 0.93  # 95.6 % measured
    assert low < 0.06  # low texture stays mostly empty (3.3 % measured)


@pytest.mark.slow
def test_second_seed_round(scene, grown, nodes, figures):
    """GrowParams.reseed_cell: the second round of automatic seeds only adds points, at nodes the
    first round did not reach; every first-round point is the same
    (docs/validation.md#region-growing-second-seed-round)."""
    one = match_pair(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams(reseed_cell=0), scene.height_range
    )
    two = grown[0]
    key = lambda r: r["x1"] + 1e5 * r["y1"]
    kept = np.isin(key(two), key(one))
    figures.report("points with one seed round", len(one))
    figures.report("points with two", len(two))
    np.testing.assert_array_equal(two[kept], one)
    assert (~kept).sum() > 40
    x2, y2, _ = scene.truth(one["x1"], one["y1"])
    _, low_one, _, matchable_one = coverage(
        one, np.hypot(one["x2"] - x2, one["y2"] - y2), nodes, figures, "one seed round"
    )
    _, low_two, _, matchable_two = coverage(two, grown[1], nodes, figures, "two seed rounds")
    assert matchable_two > matchable_one + 0.015 and low_two <= low_one + 0.005
    with pytest.raises(InputError, match="reseed cell"):
        GrowParams(reseed_cell=2).check()


@pytest.mark.slow
@pytest.mark.ratchet
def test_wide_template_option(scene, grown, nodes, figures):
    """GrowParams.wide_template 27 (off by default): more textured nodes covered, none beyond 1 px; the
    nodes of the default run are kept up to a few the growth order changes
    (docs/validation.md#region-growing-wide-template)."""
    records = match_pair(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        GrowParams(wide_template=27),
        scene.height_range,
    )
    x2, y2, cls = scene.truth(records["x1"], records["y1"])
    error = np.hypot(records["x2"] - x2, records["y2"] - y2)
    single = np.isin(cls, SINGLE_SURFACE)
    figures.report("points with the wide template 27", len(records), note=f"default {len(grown[0])}")
    figures.report("fields RMS", rms(error[single]), "px")
    figures.report("fields > 1 px", 100 * np.mean(error[single] > 1), "%")
    textured, low, on_low, _ = coverage(records, error, nodes, figures, "wide template 27")
    assert textured > 0.9 and len(records) > 1.3 * len(grown[0])
    kept = np.isin(grown[0]["x1"] + 1e5 * grown[0]["y1"], records["x1"] + 1e5 * records["y1"])
    figures.report("default points kept", kept.sum(), note=f"of {len(kept)}")
    assert kept.mean() > 0.99
    assert rms(error[single]) < 0.23 and np.mean(error[single] > 1.0) < 0.005
    assert np.mean(on_low > 1.0) < 0.005 and rms(on_low) < 0.4
    # every ellipse within the acceptance's 0.1 px as measured; the wide window's reported 27 / 19 times
    assert np.all(records["semi_major"] < 0.1 * 27 / 19)
    with pytest.raises(InputError, match="wide template"):
        GrowParams(wide_template=19).check()


@pytest.mark.slow
def test_determinism_workers_and_tiles(scene):
    params = GrowParams(tile=256)
    args = (scene.image1, scene.image2, scene.model1, scene.model2)
    a = match_pair(ImagePair(*args), params, scene.height_range, workers=1)
    b = match_pair(ImagePair(*args), params, scene.height_range, workers=2)
    np.testing.assert_array_equal(a, b)
    c = match_pair(ImagePair(*args), GrowParams(tile=320), scene.height_range, workers=2)
    key_a = {(x, y): i for i, (x, y) in enumerate(zip(a["x1"], a["y1"]))}
    pairs = np.array([(key_a[(x, y)], j) for j, (x, y) in enumerate(zip(c["x1"], c["y1"])) if (x, y) in key_a])
    assert len(pairs) > 0.85 * max(len(a), len(c))
    d = np.hypot(a["x2"][pairs[:, 0]] - c["x2"][pairs[:, 1]], a["y2"][pairs[:, 0]] - c["y2"][pairs[:, 1]])
    assert np.percentile(d, 99) < 0.1


@pytest.mark.slow
def test_given_seeds_alone_and_with_automatic_ones(scene, grown):
    """Seeds from already matched points (e.g. the block's tie points): alone, every point grows
    from one of them (seed id = index into the seeds) and agrees with the automatic result where
    both have a node; with automatic seeds too, tiles without a given seed fill as well and the
    automatic seed ids start after the given ones."""
    records = grown[0]
    far = records[np.argsort(records["rho"])[::-1][:3]]  # three strong points as seeds
    args = (scene.image1, scene.image2, scene.model1, scene.model2)
    alone = match_pair(ImagePair(*args), GrowParams(), scene.height_range, seeds=far, automatic=False)
    assert len(alone) > 100 and set(alone["seed"]) <= {0, 1, 2}
    key = {(x, y): i for i, (x, y) in enumerate(zip(records["x1"], records["y1"]))}
    pairs = np.array([(key[(x, y)], j) for j, (x, y) in enumerate(zip(alone["x1"], alone["y1"])) if (x, y) in key])
    assert len(pairs) > 0.95 * len(alone)
    d = np.hypot(
        records["x2"][pairs[:, 0]] - alone["x2"][pairs[:, 1]], records["y2"][pairs[:, 0]] - alone["y2"][pairs[:, 1]]
    )
    assert np.percentile(d, 99) < 0.05
    both = match_pair(ImagePair(*args), GrowParams(), scene.height_range, seeds=far, automatic=True)
    assert len(both) >= 0.99 * len(records) and (both["seed"] >= 3).any()
    with pytest.raises(InputError, match="needs seeds"):
        match_pair(ImagePair(*args), GrowParams(), scene.height_range, automatic=False)


@pytest.mark.slow
def test_pair_seeds_rematch_stored_points(scene, grown):
    """Tie points (MultiPoints with block image ids) become pair seeds re-matched on the images the
    growth uses: their image-2 positions agree with the region-grown ones they were taken from,
    also when the stored positions are 1.5 px off (docs/validation.md#region-growing-resolution-adaptation)."""
    from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
    from pushbroom.algorithms.matching.region_growing_strategy import pair_seeds
    from pushbroom.algorithms.matching.stereo_set import StereoSet

    records = grown[0][::25]
    n = len(records)
    pts = np.zeros(n, POINT_DTYPE)
    pts["id"] = np.arange(n)
    obs = np.zeros(2 * n, OBS_DTYPE)
    obs["point_id"] = np.repeat(np.arange(n), 2)
    obs["image_id"] = np.tile([7, 9], n)
    obs["col"][0::2], obs["row"][0::2] = records["x1"], records["y1"]
    obs["col"][1::2], obs["row"][1::2] = records["x2"] + 1.5, records["y2"] - 1.5
    stereo = StereoSet.of(
        [scene.image1, scene.image2], [scene.model1, scene.model2], ids=[7, 9], heights=scene.height_range
    )
    seeds = pair_seeds(stereo, 1, MultiPoints(pts, obs), GrowParams())
    assert len(seeds) > 0.35 * n
    np.testing.assert_array_equal(np.isin(seeds["x1"], records["x1"]), True)
    k = np.searchsorted(
        records["x1"] + 1e5 * records["y1"],
        seeds["x1"] + 1e5 * seeds["y1"],
        sorter=np.argsort(records["x1"] + 1e5 * records["y1"]),
    )
    ref = records[np.argsort(records["x1"] + 1e5 * records["y1"])[k]]
    assert np.percentile(np.hypot(seeds["x2"] - ref["x2"], seeds["y2"] - ref["y2"]), 95) < 0.05


@pytest.mark.slow
def test_transfer_points_with_guide(scene, grown):
    records = grown[0]
    guide = records[::2]
    x1 = records["x1"][1::2] + 3.0
    y1 = records["y1"][1::2] - 2.0
    out, ok = transfer_points(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        x1,
        y1,
        GrowParams(),
        scene.height_range,
        guide=guide,
    )
    assert len(out) == len(x1) and ok.mean() > 0.6
    x2, y2, cls = scene.truth(x1[ok], y1[ok])
    error = np.hypot(out["x2"][ok] - x2, out["y2"][ok] - y2)
    assert np.median(error) < 0.3
    np.testing.assert_array_equal(out["x1"], x1)


@pytest.mark.slow
def test_given_seeds(scene, grown):
    from pushbroom.algorithms.matching.seeds import automatic_seeds, seeds_from_points

    auto = automatic_seeds(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams(), scene.height_range
    )
    seeds, ok = seeds_from_points(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        auto["x1"][:3],
        auto["y1"][:3],
        GrowParams(),
        scene.height_range,
    )
    assert ok.any()
    records = match_pair(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        GrowParams(),
        scene.height_range,
        seeds=seeds[ok],
    )
    assert len(records) > 200 and set(np.unique(records["seed"])) <= set(np.flatnonzero(ok))


def test_no_overlap_is_an_input_error(scene):
    class Far:
        size = scene.model2.size

        def ground_to_image(self, lon, lat, h):
            x, y = scene.model2.ground_to_image(lon, lat, h)
            return np.asarray(x) + 50000.0, y

    with pytest.raises(InputError, match="do not overlap"):
        match_pair(ImagePair(scene.image1, scene.image2, scene.model1, Far()), GrowParams(), scene.height_range)


def test_blank_image_gives_empty_result_and_warning(scene):
    blank = Image(np.full((599, 300), 80.0, np.float32))
    feedback = Feedback()
    records = match_pair(
        ImagePair(scene.image1, blank, scene.model1, scene.model2), GrowParams(), scene.height_range, feedback=feedback
    )
    assert len(records) == 0
    assert any("Warning" in m and "no matched point" in m for m in feedback.messages)


def test_image_smaller_than_template(scene):
    with pytest.raises(InputError, match="smaller than the matching template"):
        match_pair(
            ImagePair(Image(texture((12, 12), 1)), scene.image2, scene.model1, scene.model2),
            GrowParams(),
            scene.height_range,
        )


def test_height_range_required_for_spot(scene):
    with pytest.raises(InputError, match="height range"):
        match_pair(ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams())


def test_cancel(scene):
    with pytest.raises(CancelledError):
        match_pair(
            ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
            GrowParams(),
            scene.height_range,
            feedback=Feedback(cancel_after=0),
        )
