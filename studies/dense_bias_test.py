"""Issue 39: LSM's template smooths the town's height steps, where the semi-global positions are better
(studies/README.md#dense_choice). Does the bias test (dense/refine.py: a node keeps its semi-global position where its
refined neighbours' moves along the epipolar line are systematic, |mean| > bound * sd over 1.5 templates) find those
places, on the simulated triplet and on real images, and what does it do to the DSM, class by class?

On two 3 km simulated SPOT 5 triplets (HRG, HRS1, HRS2; the supplied models, the DSM's height range +- 100 m): the
calibration scene (SceneConfig.small(), seed 1, the one `make bench-peers` compares with CARS) and the check scene of
studies/dense_precision.py (seed 2, 4 km west: small fields among forest). Dense matching with the default
DenseParams but 256 px tiles, at the settings of SETTINGS (the bound b, 0: no test; the census factor k,
DenseParams.census_error); every point intersected with the TRUE models (the error is the matching's alone) and the
product's image sigmas (dense/precision.py), and the dense pipeline model's 10 m DSM of them (studies/sim_dense.py:
cells, FALLBACK off, RADIUS 1, FILL 10) against the true DSM at the evaluation cells, by class
(tests/helpers/dsm_comparison.py). Per row: the points with a position the test kept semi-global, by class of the
point's true cell; the non-water cells from their own points and filled; the matching's seconds (2 threads); the RMS
by class.

Then the real Pleiades images (the triplet's img_02 -> img_01 and the Ventoux pair, ../shared/data): the central
512 px tile of the first image, the share of the refined nodes the test keeps at each bound."""

import tempfile

import numpy as np
from scipy.spatial import cKDTree

from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.refine import lattice_tests
from pushbroom.algorithms.matching.points import SEMI_GLOBAL
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from studies.sim_dense import TruthCloud, dense_points, intersect_truth, model_dem, real_tiles, rms
from tests.helpers.dsm_comparison import CLASSES, Truth

#: the test's bounds at the product's census factor (0: off), for the real images
BOUNDS = (0.0, 0.6, 0.8, 1.0)
#: (bound b, census factor k) of the simulated rows
SETTINGS = ((0.0, DenseParams.census_error), (0.8, 1.0), (0.6, 1.5), (0.8, 1.5), (1.0, 1.5), (0.8, 2.0))
SCENES = {
    "seed 1 (calibration)": SceneConfig.small(),
    "seed 2, 4 km west": SceneConfig.small(seed=2, centre_lon=-84.235),
}


def kept_semi_global(cloud: TruthCloud) -> np.ndarray:
    """Per intersected point, whether the test kept its positions semi-global (points.SEMI_GLOBAL)."""
    pts = cloud.points.points
    return (pts["flags"][np.searchsorted(pts["id"], cloud.result.point)] & SEMI_GLOBAL) != 0


def real_shares() -> None:
    """The real part (module docstring), at the product's census factor."""
    for tile in real_tiles(DenseParams()):
        shares = []
        for bound in BOUNDS[1:]:
            refined, kept = lattice_tests(tile.dense, tile.refined, tile.grid, DenseParams(bias_bound=bound))
            shares.append(f"{bound:g}: {kept.sum() / np.isfinite(refined.rho).sum():.1%}")
        print(
            f"{tile.label}: {np.isfinite(refined.rho).sum()} refined nodes; kept semi-global at the bounds "
            + ", ".join(shares)
        )


def simulated(label: str, config: SceneConfig) -> None:
    """The simulated part (module docstring) on one scene."""
    paths = simulate_scene(config, tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    zones = {name: truth.cls == c for c, name in CLASSES.items()}
    zones.update({"building edges": truth.edge, "open near forest, city or water": truth.near})
    land = ~truth.water
    print(
        f"\n{label}\n| b | k | kept semi-global: "
        + ", ".join(CLASSES.values())
        + " | own cells | filled | matching (s) | "
        + " | ".join(zones)
        + " |\n|"
        + "---|" * (6 + len(zones))
    )
    for bound, factor in SETTINGS:
        points, seconds = dense_points(paths, DenseParams(tile=256, bias_bound=bound, census_error=factor))
        sigma = precision.image_sigmas(points.points, points.observations, IMAGE_SIGMA, precision.SPOT.factors)
        cloud = TruthCloud(points, intersect_truth(points, truth, sigma), seconds)
        res = cloud.result
        x, y = reproject(res.lon, res.lat, wgs84(), truth.srs)
        _, nearest = cKDTree(np.column_stack([truth.x, truth.y])).query(np.column_stack([x, y]))
        point_class = truth.cls[nearest]
        kept = kept_semi_global(cloud)
        dh, mask = model_dem(cloud, truth, tempfile.mkdtemp())
        print(
            f"| {bound or 'off'} | {factor if bound else '-'} | "
            + " / ".join(f"{kept[point_class == c].mean():.0%}" for c in CLASSES)
            + f" | {np.mean(mask[land] == 0):.1%} | {np.mean(mask[land] == 1):.1%} | {cloud.seconds:.0f} | "
            + " | ".join(f"{rms(dh[m]):.2f}" for m in zones.values())
            + " |",
            flush=True,
        )


def main() -> None:
    real_shares()
    for label, config in SCENES.items():
        simulated(label, config)


if __name__ == "__main__":
    main()
