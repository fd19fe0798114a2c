"""A wider second LSM window in the dense refinement: does it measure the cells the default template leaves?

1. The 3 km simulated SPOT 5 triplet (studies/sim_dense.py: dense matching with default DenseParams but 256 px
   tiles, the points intersected with the TRUE models), DenseParams.wide_template off and 31 px: the points refined,
   the matching time, the dense pipeline model's 10 m DSM against the true DSM by class, and the share of the
   non-water cells from their own points (mask 0), the cells around (2) and filled (1).
2. On that DSM's cloud with the wide window, the cells' tier rule (cell_dem.py: a three-ray point of the cells
   around before a two-ray one of the cell's own) against own points first (both refined tiers as one), RADIUS 1,
   no fill.
3. Where the positions come from, on the HRG -> HRS1 tile of tests/algorithms/dense/test_dense_strategy.py (every
   pixel, against the true conjugates): per class, the share of the matched nodes the 19 px LSM refines and their
   RMS error, the share the 31 px window adds and theirs, and the semi-global positions' RMS on the same nodes.
4. Where ../shared/data holds it, the Pleiades triplet (img_02 the reference, over the terrain's heights 40 to 535 m,
   2 threads): the points refined in every position and the matching time, off and on, twice each, alternating."""

import tempfile
import time

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.pair_tile import match_pair_tile
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.refine import Conjugates, refine_positions
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.simulation.terrain import CLASSES
from pushbroom.algorithms.surface.cell_dem import (
    THREE_RAYS,
    UNREFINED,
    CellSettings,
    cells_on_grid,
    point_tiers,
)
from pushbroom.algorithms.surface.tin_dem import DemParams
from studies.sim_dense import BEFORE, TruthCloud, evaluation_grid, model_dem, rms, truth_cloud
from tests.benchmarks.benchutil import SHARED_DATA
from tests.helpers.dsm_comparison import Truth
from tests.helpers.matching_scene import Scene

WIDE = 31
BOX = (44, 44, 556, 556)  # test_dense_strategy.py's tile


def table_row(dh, truth):
    return ", ".join(f"{zone} {v[2]:.2f} m" for zone, v in truth.table(dh, np.isfinite(dh)).items())


def simulated(paths, truth):
    """Parts 1 and 2 (module docstring); the cloud with the wide window."""
    for wide in (0, WIDE):
        cloud = truth_cloud(paths, truth, DenseParams(tile=256, wide_template=wide, **BEFORE))
        dh, mask = model_dem(cloud, truth, tempfile.mkdtemp())
        source = mask[~truth.water]
        print(
            f"wide template {wide or 'off'}: {np.isfinite(cloud.points.points['rho_min']).mean():.1%} of the points "
            f"refined, matching {cloud.seconds:.0f} s; non-water cells: own points {np.mean(source == 0):.1%}, the "
            f"cells around {np.mean(source == 2):.1%}, filled {np.mean(source == 1):.1%}"
        )
        print(f"   10 m DSM - true DSM, RMS: {table_row(dh, truth)}")
    return cloud


def tier_rule(cloud: TruthCloud, truth):
    """Part 2 (module docstring)."""
    res = cloud.result
    ok = res.ok
    x, y = reproject(res.lon[ok], res.lat[ok], wgs84(), truth.srs)
    refined = np.isfinite(cloud.rho()[ok])
    tier = point_tiers(cloud.rho()[ok], res.rays[ok])
    grid, i, j = evaluation_grid(truth)
    settings = CellSettings(k=DemParams().k, fallback=False, radius=1)
    for label, t in (
        ("tiers (the product): three rays, then two, then the ring", tier),
        ("own points first (the refined tiers as one)", np.where(refined, THREE_RAYS, UNREFINED)),
    ):
        cells = cells_on_grid(x, y, res.h[ok], None, grid, settings, tier=t)
        ring = cells.ring[i, j][~truth.water]
        print(f"{label}: own cells {np.mean(ring == 0):.1%}")
        print(f"   10 m DSM - true DSM (RADIUS 1, no fill), RMS: {table_row(cells.heights[i, j] - truth.h, truth)}")


def tile(paths):
    """Part 3 (module docstring)."""
    scene = Scene(paths, "HRG", "HRS1")
    x1, y1, x2, y2, info = match_pair_tile(
        scene.image1, scene.image2, scene.model1, scene.model2, BOX, scene.height_range, DenseParams()
    )
    tx, ty, cls = scene.truth(x1, y1)
    pair = ImagePair(scene.image1, scene.image2, scene.model1, scene.model2)
    heights = info["grid"].heights[::2]
    small = refine_positions(
        pair, Conjugates(x1, y1, x2, y2), heights, DenseParams(wide_template=0, **BEFORE).refinement()
    )
    wide = refine_positions(
        pair, Conjugates(x1, y1, x2, y2), heights, DenseParams(wide_template=WIDE, **BEFORE).refinement()
    )
    matched = np.isfinite(x2)
    first, both = np.isfinite(small[2]), np.isfinite(wide[2])
    added = both & ~first
    semi_global = np.hypot(x2 - tx, y2 - ty)
    for c in np.unique(cls):
        m = matched & (cls == c)
        print(
            f"tile, {CLASSES[c]}: 19 px refines {first[m].mean():.1%} of the matched (RMS "
            f"{rms(np.hypot(small[0] - tx, small[1] - ty)[m & first]):.3f} px, semi-global there "
            f"{rms(semi_global[m & first]):.3f}); the {WIDE} px window adds {added[m].mean():.1%} (RMS "
            f"{rms(np.hypot(wide[0] - tx, wide[1] - ty)[m & added]):.3f} px, semi-global there "
            f"{rms(semi_global[m & added]):.3f})"
        )


def pleiades():
    """Part 4 (module docstring)."""
    images = [SHARED_DATA / "pleiades_triplet" / f"img_0{k}.tif" for k in (2, 1, 3)]
    if not all(p.exists() for p in images):
        print(f"{images[0].parent} is absent: no Pleiades run")
        return
    models = [sensors.load(str(p)) for p in images]
    for wide in (0, WIDE, 0, WIDE):
        t = time.perf_counter()
        parts, _ = match_dense_tiles(
            [str(p) for p in images],
            models,
            tempfile.mkdtemp() + "/dense",
            names=["two", "one", "three"],
            params=DenseParams(wide_template=wide, **BEFORE),
            height_range=(40.0, 535.0),
            execution=Execution("threads", 2),
        )
        seconds = time.perf_counter() - t
        rho = np.concatenate([p.points["rho_min"] for p in parts])
        print(
            f"Pleiades triplet, wide template {wide or 'off'}: {rho.size} points, "
            f"{np.isfinite(rho).mean():.1%} refined, {seconds:.0f} s",
            flush=True,
        )


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    tier_rule(simulated(paths, truth), truth)
    tile(paths)
    pleiades()


if __name__ == "__main__":
    main()
