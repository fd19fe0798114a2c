"""Refine every dense pixel by LSM, or only a lattice of them? On the 3 km simulated SPOT 5 triplet's
HRG -> HRS1 tile of 512 px (supplied models, the DSM's height range +- 100 m), the semi-global positions of
every pixel (pair_tile.match_pair_tile), then: LSM at every pixel (refine.refine_positions, the product's
way), against LSM on a lattice of every k-th pixel whose shifts (refined minus semi-global position) are
interpolated bilinearly to the pixels between, where the four lattice nodes around are all refined. Per
way: the share of the matched pixels refined, their median |error| against the truth on open ground
(bare fields and crops) and within forest and city, and the refinement's time. Then a wide second template:
the matched pixels the 19 px LSM left, tried again with a WIDE px one (same criteria): how many it adds, and
how accurate they are."""

import tempfile
import time
from dataclasses import replace

import numpy as np

from pushbroom.algorithms.dense.pair_tile import match_pair_tile
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.refine import Conjugates, refine_positions
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.simulation.terrain import BARE, CROPS
from tests.helpers.matching_scene import Scene

BOX = (44, 44, 556, 556)
STEPS = (1, 2, 3, 4)
WIDE = 31  # px: the wide second template


def lattice_shifts(shift, step):
    """`shift` (rows, cols) known at every step-th pixel (others NaN), bilinear at every pixel where the four
    lattice nodes around it are known (NaN elsewhere)."""
    rows, cols = shift.shape
    i, j = np.mgrid[0:rows, 0:cols]
    i0, j0 = (i // step) * step, (j // step) * step
    i1, j1 = np.minimum(i0 + step, (rows - 1) // step * step), np.minimum(j0 + step, (cols - 1) // step * step)
    ti = np.where(i1 > i0, (i - i0) / step, 0.0)
    tj = np.where(j1 > j0, (j - j0) / step, 0.0)
    return (1 - ti) * ((1 - tj) * shift[i0, j0] + tj * shift[i0, j1]) + ti * (
        (1 - tj) * shift[i1, j0] + tj * shift[i1, j1]
    )


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    scene = Scene(paths, "HRG", "HRS1")
    params = DenseParams()
    x1, y1, x2, y2, info = match_pair_tile(
        scene.image1, scene.image2, scene.model1, scene.model2, BOX, scene.height_range, params
    )
    tx, ty, cls = scene.truth(x1, y1)
    shape = (BOX[3] - BOX[1], BOX[2] - BOX[0])
    matched = np.isfinite(x2)
    open_ground = np.isin(cls, (BARE, CROPS))
    before = np.hypot(x2 - tx, y2 - ty)
    print(
        f"semi-global: {matched.mean():.1%} of the tile's pixels matched, median |error| open ground "
        f"{np.nanmedian(before[open_ground]):.3f} px, forest and city {np.nanmedian(before[~open_ground]):.3f} px"
    )
    for step in STEPS:
        on = matched & (((y1 - BOX[1] - 0.5) % step == 0) & ((x1 - BOX[0] - 0.5) % step == 0))
        t = time.perf_counter()
        rx, ry, rho, *_ = refine_positions(
            ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
            Conjugates(x1[on], y1[on], x2[on], y2[on]),
            info["grid"].heights[::2],
            replace(params, max_shift=0.5, wide_template=0).refinement(),
        )
        seconds = time.perf_counter() - t
        sx, sy = np.full(x1.size, np.nan), np.full(x1.size, np.nan)
        ok = np.isfinite(rho)
        sx[np.flatnonzero(on)[ok]] = (rx - x2[on])[ok]
        sy[np.flatnonzero(on)[ok]] = (ry - y2[on])[ok]
        if step > 1:
            sx, sy = (lattice_shifts(v.reshape(shape), step).ravel() for v in (sx, sy))
        refined = matched & np.isfinite(sx)
        err = np.hypot(x2 + sx - tx, y2 + sy - ty)
        print(
            f"LSM every {step} px: {refined.sum() / matched.sum():.1%} of the matched pixels refined, median "
            f"|error| open ground {np.median(err[refined & open_ground]):.3f} px (semi-global there "
            f"{np.median(before[refined & open_ground]):.3f}), forest and city "
            f"{np.median(err[refined & ~open_ground]):.3f} px; LSM {seconds:.1f} s"
        )
        if step == 1:
            first = refined.copy()
    left = matched & ~first
    t = time.perf_counter()
    wx, wy, wrho, *_ = refine_positions(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        Conjugates(x1[left], y1[left], x2[left], y2[left]),
        info["grid"].heights[::2],
        replace(params, template=WIDE, max_shift=0.5, wide_template=0).refinement(),
    )
    seconds = time.perf_counter() - t
    added = np.isfinite(wrho)
    err = np.hypot(wx - tx[left], wy - ty[left])[added]
    on_open = open_ground[left][added]
    print(
        f"then a {WIDE} px template on the {left.sum()} matched pixels left: refines {added.sum()} more "
        f"({(first.sum() + added.sum()) / matched.sum():.1%} of the matched in all), median |error| open ground "
        f"{np.median(err[on_open]):.3f} px, forest and city {np.median(err[~on_open]):.3f} px; LSM {seconds:.1f} s"
    )


if __name__ == "__main__":
    main()
