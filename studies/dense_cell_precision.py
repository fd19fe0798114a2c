"""Issue 39: is the DSM's precision raster true, class by class, for two-ray and three-ray cells?

On the 3 km simulated SPOT 5 triplet and its check scene (studies/dense_precision.SCENES; HRG, HRS1, HRS2; the
supplied models, the DSM's height range +- 100 m), dense matching with the default DenseParams but 256 px tiles;
every point intersected with the TRUE models (the error is the matching's alone) with the product's a priori image
sigmas (dense/precision.image_sigmas, IMAGE_SIGMA for the points that are not LSM's), the refined points' spread term
added as the intersection step does (precision.with_spread over surface/local_spread.py); then the per-cell DSM of
the DEM step (cell_dem.cells_on_grid: 10 m, k 3, RADIUS 1, FALLBACK off, the points' tiers) with its precision raster
(the RMS of the cell's points' sigma_h). Against the true DSM at the evaluation cells
(tests/helpers/dsm_comparison.py): RMS(dh) / RMS(precision) by class, for the cells whose points have three rays and
those whose points have two, on the cells from their own points and on those from the ring around (1 is calibrated;
issue 39 asks 0.8-1.25). A cell's points are three-ray where the DSM of the three-ray points alone gives the cell the
same height. Last, the own cells' ratio by quartile of their predicted precision within each class."""

import tempfile

import numpy as np

from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface.cell_dem import (
    THREE_RAYS,
    CellSettings,
    cells_on_grid,
    point_tiers,
)
from pushbroom.algorithms.surface.local_spread import local_metres
from studies.dense_precision import SCENES
from studies.sim_dense import dense_points, evaluation_grid, intersect_truth, rms, with_template_spread
from tests.helpers.dsm_comparison import CLASSES, Truth


def cloud(paths: dict, truth: Truth) -> dict:
    """The dense points intersected with the truth: UTM x, y, h, sigma_h (the product's) and cell_dem's tier."""
    multi, _ = dense_points(paths, DenseParams(tile=256))
    points, obs = multi.points, multi.observations
    res = intersect_truth(multi, truth, precision.image_sigmas(points, obs, IMAGE_SIGMA, precision.SPOT.factors))
    ok = res.ok
    slot = np.searchsorted(points["id"], res.point)
    refined = precision.refined_dense(points)[slot] & ok
    x, y = local_metres(res.lon, res.lat, (float(np.mean(res.lon[ok])), float(np.mean(res.lat[ok]))))
    sigma_h, _ = with_template_spread(res.sigma[:, 2], x, y, res.h, refined, truth.models[1], precision.SPOT.spread)
    ex, ey = reproject(res.lon, res.lat, wgs84(), truth.srs)
    tier = point_tiers(points["rho_min"][slot], res.rays)
    return {"x": ex[ok], "y": ey[ok], "z": res.h[ok], "sigma": sigma_h[ok], "tier": tier[ok]}


def main() -> None:
    for name, config in SCENES.items():
        print(f"\n{name}:")
        scene(config)


def scene(config: SceneConfig) -> None:
    """The tables of the module docstring for one simulated scene."""
    paths = simulate_scene(config, tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    c = cloud(paths, truth)
    grid, i, j = evaluation_grid(truth)
    settings = CellSettings(k=3.0, fallback=False, radius=1)
    cells = cells_on_grid(c["x"], c["y"], c["z"], c["sigma"], grid, settings, tier=c["tier"])
    three = c["tier"] == THREE_RAYS
    alone = cells_on_grid(c["x"][three], c["y"][three], c["z"][three], c["sigma"][three], grid, settings)
    dh = cells.heights[i, j] - truth.h
    prec = cells.precision[i, j]
    ring = cells.ring[i, j]
    is_three = alone.heights[i, j] == cells.heights[i, j]
    zones = {name: truth.cls == k for k, name in CLASSES.items()}
    zones.update({"building edges": truth.edge, "open near forest, city or water": truth.near})
    usable = np.isfinite(dh) & np.isfinite(prec)
    print("| cells | " + " | ".join(zones) + " |\n|" + "---|" * (1 + len(zones)))
    for label, rays in (("three rays", is_three), ("two rays", ~is_three)):
        for where, r in (("own points", 0), ("the ring around", 1)):
            row = []
            for m in zones.values():
                sel = m & rays & (ring == r) & usable
                row.append(f"{rms(dh[sel]) / rms(prec[sel]):.2f} ({sel.sum()})" if sel.sum() >= 20 else "-")
            print(f"| {label}, {where} | " + " | ".join(row) + " |")
    # the own cells by quartile of their predicted precision, within each class
    print("\n| own cells, quartile of the precision | " + " | ".join(zones) + " |\n|" + "---|" * (1 + len(zones)))
    for quarter in range(4):
        row = []
        for m in zones.values():
            sel = m & (ring == 0) & usable
            edges = np.quantile(prec[sel], [0.25, 0.5, 0.75]) if sel.sum() >= 80 else None
            part = sel & (np.digitize(prec, edges) == quarter) if edges is not None else sel & False
            row.append(f"{rms(dh[part]) / rms(prec[part]):.2f}" if part.sum() >= 20 else "-")
        print(f"| {'first second third fourth'.split()[quarter]} | " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
