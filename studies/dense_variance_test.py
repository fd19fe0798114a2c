"""Issue 39: the dense refinement's largest shift, and the variance test that keeps a semi-global position where
LSM's affine does not fit one surface (dense/refine.py). How do they change the DSM, class by class, and how many
cells do they measure?

On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the supplied models, the DSM's height range +- 100 m),
dense matching with the default DenseParams but 256 px tiles and, per row, the refinement's largest shift and the
variance test's bound Q (DenseParams.max_shift, max_residual; 0: no test); every point intersected with the TRUE
models (the error is the matching's alone), and the dense pipeline model's 10 m DSM of them (studies/sim_dense.py:
cells, FALLBACK off, RADIUS 1, FILL 10) against the true DSM at the evaluation cells, by class
(tests/helpers/dsm_comparison.py). Per row: the points whose every position is LSM's, those with a position the
test kept (flag SEMI_GLOBAL), the non-water cells from their own points and filled, the matching's seconds (2
threads), and the RMS by class.

Then the real Pleiades images (the triplet's img_02 -> img_01 and the Ventoux pair, ../shared/data): the central
512 px tile of the first image, dense positions refined by LSM (DenseParams.refinement), and q of the accepted
nodes against the image noise matching.image_noise estimates: is one surface's residual the noise there too?"""

import tempfile
from pathlib import Path

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dense.pair_tile import match_pair_tile
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.precision import refined_dense
from pushbroom.algorithms.dense.refine import Conjugates, refine_positions, residual_ratio
from pushbroom.algorithms.matching.image_noise import image_noise
from pushbroom.algorithms.matching.imagery import as_image
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.points import SEMI_GLOBAL
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from studies.sim_dense import model_dem, rms, truth_cloud
from tests.helpers.dsm_comparison import CLASSES, Truth

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
REAL = {
    "Pleiades triplet, img_02 -> img_01": ("pleiades_triplet/img_02.tif", "pleiades_triplet/img_01.tif"),
    "Ventoux pair": ("pleiades_pair_ventoux/left_image.tif", "pleiades_pair_ventoux/right_image.tif"),
}
#: (largest shift px, Q) per row
ROWS = ((0.5, 0.0), (1.0, 0.0), (1.0, 1.5), (1.0, 2.0), (1.0, 2.5), (1.0, 3.0))


def main() -> None:
    real_residuals()
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    zones = {name: truth.cls == c for c, name in CLASSES.items()}
    zones.update({"building edges": truth.edge, "open near forest, city or water": truth.near})
    land = ~truth.water
    print(
        "| largest shift (px) | Q | LSM's points | kept semi-global | own cells | filled cells | matching (s) | "
        + " | ".join(zones)
        + " |\n|"
        + "---|" * (7 + len(zones))
    )
    own = []
    for shift, bound in ROWS:
        cloud = truth_cloud(paths, truth, DenseParams(tile=256, max_shift=shift, max_residual=bound))
        points = cloud.points.points
        dh, mask = model_dem(cloud, truth, tempfile.mkdtemp())
        print(
            f"| {shift:g} | {bound:g} | {refined_dense(points).mean():.1%} | "
            f"{((points['flags'] & SEMI_GLOBAL) != 0).mean():.1%} | {np.mean(mask[land] == 0):.1%} | "
            f"{np.mean(mask[land] == 1):.1%} | {cloud.seconds:.0f} | "
            + " | ".join(f"{rms(dh[m]):.2f}" for m in zones.values())
            + " |",
            flush=True,
        )
        own.append(
            f"| {shift:g} | {bound:g} | " + " | ".join(f"{np.mean(mask[m] == 0):.0%}" for m in zones.values()) + " |"
        )
    print("\ncells from their own points, by class:\n| largest shift (px) | Q | " + " | ".join(zones) + " |")
    print("|" + "---|" * (2 + len(zones)) + "\n" + "\n".join(own))


def real_residuals() -> None:
    """The real part (module docstring)."""
    for label, files in REAL.items():
        paths = [SHARED / f for f in files]
        if not all(p.exists() for p in paths):
            print(f"{label}: not in {SHARED}")
            continue
        models = [sensors.load(p) for p in paths]
        images = [as_image(p, saturation=True) for p in paths]
        noise = image_noise(images[0])
        cols, rows = models[0].size
        box = (cols // 2 - 256, rows // 2 - 256, cols // 2 + 256, rows // 2 + 256)
        heights = models[0].height_range
        x1, y1, x2, y2, info = match_pair_tile(images[0], images[1], models[0], models[1], box, heights, DenseParams())
        pair = ImagePair(images[0], images[1], models[0], models[1])
        r = refine_positions(pair, Conjugates(x1, y1, x2, y2), info["grid"].heights[::2], DenseParams().refinement())
        ok = np.isfinite(r.rho)
        q = residual_ratio(images[0], x1[ok], y1[ok], r.rho[ok], DenseParams().template, noise)
        p10, p50, p90 = np.nanpercentile(q, [10, 50, 90])
        print(
            f"{label}: image noise {noise:.2f} DN; q of the {ok.sum()} accepted nodes, 10th / 50th / 90th percentile "
            f"{p10:.2f} / {p50:.2f} / {p90:.2f}; above 2: {np.mean(q > 2):.1%}"
        )


if __name__ == "__main__":
    main()
