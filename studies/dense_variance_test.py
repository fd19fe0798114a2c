"""Issue 39: the dense refinement's largest shift, and a variance test that would keep a semi-global position where
LSM's affine does not fit one surface. How do they change the DSM, class by class, and how many cells do they
measure? And does the test's noise model hold on real images?

The test (studies/dense_choice.py): q = s_t sqrt(1 - rho^2) / sigma_n, LSM's template residual after its
radiometric fit over the image noise (Immerkaer's robust estimator); one surface under an affine leaves about the
noise, a template over several heights more. Where q > Q, a point takes its semi-global position, and still counts
as measured.

On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the supplied models, the DSM's height range +- 100 m), dense
matching with the default DenseParams but 256 px tiles, at the largest shifts of ROWS, and once without the
refinement (every position the semi-global one); every point intersected with the TRUE models (the error is the
matching's alone), and the dense pipeline model's 10 m DSM of them (studies/sim_dense.py: cells, FALLBACK off,
RADIUS 1, FILL 10) against the true DSM at the evaluation cells, by class (tests/helpers/dsm_comparison.py). Per
row: the points whose positions are all LSM's, those the test gave their semi-global positions, the non-water cells
from their own points and filled, the matching's seconds (2 threads), and the RMS by class.

Then the real Pleiades images (the triplet's img_02 -> img_01 and the Ventoux pair, ../shared/data): the central
512 px tile of the first image, dense positions refined by LSM (DenseParams.refinement), and q of the accepted
nodes: is one surface's residual the noise there too?"""

import dataclasses
import tempfile

import numpy as np
from osgeo import gdal

from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from studies.dense_choice import noise_sigma, residual_q
from studies.sim_dense import TruthCloud, model_dem, real_tiles, rms, truth_cloud
from tests.helpers.dsm_comparison import CLASSES, Truth

#: the refinement's largest shifts (px), and the test's bounds Q at the last of them
SHIFTS, BOUNDS = (0.5, 1.0), (1.5, 2.0, 2.5, 3.0)


def with_semi_global(cloud: TruthCloud, semi_global: TruthCloud, where: np.ndarray) -> TruthCloud:
    """`cloud` with the intersected positions of `semi_global` (the same points) where `where`; their rho stays
    LSM's (measured)."""
    a, b = cloud.result, semi_global.result
    assert np.array_equal(a.point, b.point)
    return cloud._replace(
        result=dataclasses.replace(a, **{k: np.where(where, getattr(b, k), getattr(a, k)) for k in ("lon", "lat", "h")})
    )


def residuals(cloud: TruthCloud, image: np.ndarray, sigma_n: float) -> np.ndarray:
    """q of each intersected point of `cloud` at its reference image position."""
    obs = cloud.points.observations
    ref = obs[obs["image_id"] == 1]
    ref = ref[np.searchsorted(ref["point_id"], cloud.result.point)]
    return residual_q(image, ref["col"], ref["row"], cloud.rho(), sigma_n)


def real_residuals() -> None:
    """The real part (module docstring)."""
    for tile in real_tiles(DenseParams()):
        array = gdal.Open(str(tile.first)).ReadAsArray().astype(float)
        sigma_n = noise_sigma(array)
        ok = np.isfinite(tile.refined.rho)
        q = residual_q(array, tile.dense.x1[ok], tile.dense.y1[ok], tile.refined.rho[ok], sigma_n)
        p10, p50, p90 = np.nanpercentile(q, [10, 50, 90])
        print(
            f"{tile.label}: image noise {sigma_n:.2f} DN; q of the {ok.sum()} accepted nodes, 10th / 50th / 90th "
            f"percentile {p10:.2f} / {p50:.2f} / {p90:.2f}; above 2: {np.mean(q > 2):.1%}"
        )


def main() -> None:
    real_residuals()
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    zones = {name: truth.cls == c for c, name in CLASSES.items()}
    zones.update({"building edges": truth.edge, "open near forest, city or water": truth.near})
    land = ~truth.water
    image = gdal.Open(str(paths["images"]["HRG"]["imagery"])).ReadAsArray().astype(float)
    sigma_n = noise_sigma(image)
    semi_global = truth_cloud(paths, truth, DenseParams(tile=256, lsm=False))
    print(
        "| largest shift (px) | Q | LSM's points | semi-global by the test | own cells | filled cells | matching (s) | "
        + " | ".join(zones)
        + " |\n|"
        + "---|" * (7 + len(zones))
    )
    own = []
    for shift in SHIFTS:
        cloud = truth_cloud(paths, truth, DenseParams(tile=256, max_shift=shift))
        q = residuals(cloud, image, sigma_n)
        for bound in (0.0, *BOUNDS) if shift == SHIFTS[-1] else (0.0,):
            kept = np.isfinite(q) & (q > bound) if bound else np.zeros(q.size, bool)
            dh, mask = model_dem(with_semi_global(cloud, semi_global, kept), truth, tempfile.mkdtemp())
            print(
                f"| {shift:g} | {bound or 'off'} | {np.mean(np.isfinite(cloud.rho()) & ~kept):.1%} | "
                f"{kept.mean():.1%} | "
                f"{np.mean(mask[land] == 0):.1%} | {np.mean(mask[land] == 1):.1%} | {cloud.seconds:.0f} | "
                + " | ".join(f"{rms(dh[m]):.2f}" for m in zones.values())
                + " |",
                flush=True,
            )
            if not bound:
                own.append(
                    f"| {shift:g} | " + " | ".join(f"{np.mean(mask[m] == 0):.0%}" for m in zones.values()) + " |"
                )
    print("\ncells from their own points, by class:\n| largest shift (px) | " + " | ".join(zones) + " |")
    print("|" + "---|" * (1 + len(zones)) + "\n" + "\n".join(own))


if __name__ == "__main__":
    main()
