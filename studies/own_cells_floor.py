"""Issue 39: can 95 % of the Pleiades triplet's 0.5 m cells hold a point of their own, with one point per pixel?

The triplet (img_02, img_01, img_03; ../shared/data) matched densely (default DenseParams, 2 threads, 40-535 m), its
points intersected with the supplied RPCs. A cell "holds a point of its own" as the DEM step counts it (cell_dem.py,
mask 0): a point falls inside it. On grids of several cell sizes in the points' UTM zone, over the cells whose centre
every image sees (the footprint, as make bench-peers), this counts the share of cells that hold:
- refined: a refined point (rho_min finite: the points interpolatedem uses with FALLBACK off);
- every point: any matched point;
- the DEM step's own cells: mask 0 of the per-cell DSM (cell_dem.cells_on_grid: k 3, FALLBACK off, RADIUS 1, the
  points' tiers and the product's sigma_h: precision.image_sigmas with the sensor's Calibration, the spread term
  over surface/local_spread.py), where the tier comes before the ring unless the cell's own points are predicted
  no less precise (cell_dem's precision rule); and by the tier alone (the rule before it: a cell whose own points
  are two-ray takes a three-ray point of the ring around, and is not counted as own);
- every pixel: a pixel centre of img_02, the reference, each projected to the ground (RpcModel.image_to_ground) at
  its point's height where the node matched, else at the height of the nearest matched node in the image. This is
  what a lattice of one point per pixel, every node matched and refined, could give at best: the floor the
  sampling sets, whatever the matching does.

The DEM step's rule is also compared with the tier alone and with the other order, a cell's own points first (the
best tier among them) and the ring's only where it has none: on the Pleiades triplet by the share of own cells, and
on the simulated scenes (studies/dense_precision.SCENES, the points of studies/dense_cell_precision's cloud,
intersected with the truth's models) by that share and the 10 m DSM minus the true DSM, RMS by class.

Cells the size of the pixel hold a point of their own only where the projected lattice puts one in them; the lattice
is sheared and stretched on the ground by the view angle and the slopes, so some cells get two and some none."""

import tempfile

import numpy as np
from scipy import ndimage

from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from pushbroom.algorithms.simulation import simulate_scene
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid, point_tiers
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from studies.dense_cell_precision import cloud
from studies.dense_precision import SCENES
from studies.sim_dense import evaluation_grid, rms, triplet_points, with_template_spread
from tests.helpers.dsm_comparison import CLASSES, Truth
from tests.helpers.real_dsm import footprint_mask

CELLS = (0.5, 0.6, 0.7, 0.8, 1.0)


def held(grid: Grid, inside: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(the share of the `inside` cells of `grid` that hold at least one of the points (x, y), the points per
    inside cell)."""
    c = np.floor((x - grid.x0) / grid.cell).astype(np.int64)
    r = np.floor((grid.y0 - y) / grid.cell).astype(np.int64)
    ok = (c >= 0) & (r >= 0) & (c < grid.cols) & (r < grid.rows)
    count = np.zeros(grid.shape, np.int64)
    np.add.at(count, (r[ok], c[ok]), 1)
    return float((count[inside] > 0).mean()), float(count[inside].mean())


def main() -> None:
    matched = triplet_points()
    if matched is None:
        return
    models, points = matched
    obs = points.observations
    calibration = precision.calibration_of(models)
    sigma = precision.image_sigmas(points.points, obs, IMAGE_SIGMA, calibration.factors)
    res = intersect(
        {k + 1: m for k, m in enumerate(models)},
        Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"], sigma),
    )
    ok = res.ok
    slot = np.searchsorted(points.points["id"], res.point[ok])
    refined = np.isfinite(points.points["rho_min"][slot])
    tier = point_tiers(points.points["rho_min"][slot], res.rays[ok])
    lon, lat, h = res.lon[ok], res.lat[ok], res.h[ok]
    srs = output_srs(None, lon, lat)
    x, y = reproject(lon, lat, wgs84(), srs)
    sigma_h, _ = with_template_spread(res.sigma[ok, 2], x, y, h, refined, models[0], calibration.spread)
    # every pixel centre of the reference at its node's height, or the nearest matched node's
    cols, rows = models[0].size
    ref = obs[obs["image_id"] == 1]
    at = {int(p): (c, r) for p, c, r in zip(ref["point_id"], ref["col"], ref["row"])}
    height = np.full((rows, cols), np.nan)
    for pid, hh in zip(res.point[ok], h):
        c, r = at[int(pid)]
        height[int(r), int(c)] = hh
    _, (ri, ci) = ndimage.distance_transform_edt(np.isnan(height), return_indices=True)
    height = height[ri, ci]
    jj, ii = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
    plon, plat = models[0].image_to_ground(jj.ravel(), ii.ravel(), height.ravel())
    px, py = reproject(np.asarray(plon, float), np.asarray(plat, float), wgs84(), srs)
    print(f"{len(x)} points ({refined.sum()} refined) of {rows * cols} pixels of img_02")
    print(
        "| cell (m) | footprint cells | pixels per cell | refined | the DEM step's own cells | the tier alone "
        "| own points first | "
        "every point "
        "| every pixel (the floor) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for cell in CELLS:
        x0, y1 = np.floor(px.min() / cell) * cell, np.ceil(py.max() / cell) * cell
        grid = Grid(x0, y1, cell, int(np.ceil((px.max() - x0) / cell)), int(np.ceil((y1 - py.min()) / cell)))
        inside = footprint_mask(grid, srs, models, float(np.median(h)))
        shares = [held(grid, inside, a, b)[0] for a, b in ((x[refined], y[refined]), (x, y), (px, py))]
        rules = [np.isfinite(heights) & (ring == 0) for heights, ring in the_rules(x, y, h, sigma_h, grid, tier)]
        shares[1:1] = [float(own[inside].mean()) for own in rules]
        print(
            f"| {cell:g} | {int(inside.sum())} | {held(grid, inside, px, py)[1]:.2f} | "
            + " | ".join(f"{100 * s:.1f} %" for s in shares)
            + " |"
        )
    simulated()


def the_rules(
    x: np.ndarray, y: np.ndarray, h: np.ndarray, sigma: np.ndarray, grid: Grid, tier: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(heights, ring) of the DEM step's cells (k 3, FALLBACK off, RADIUS 1) by its rule (with the points' `sigma`:
    the tier before the ring, unless the cell's own points are no less precise), by the tier alone (no sigma), and
    by a cell's own points first (the best tier among them), the ring's only where it has none."""
    settings = CellSettings(k=3.0, fallback=False, radius=1)
    rule = cells_on_grid(x, y, h, sigma, grid, settings, tier=tier)
    one = cells_on_grid(x, y, h, None, grid, settings, tier=tier)
    own = cells_on_grid(x, y, h, None, grid, settings._replace(radius=0), tier=tier)
    mine = np.isfinite(own.heights)
    return [
        (rule.heights, rule.ring),
        (one.heights, one.ring),
        (np.where(mine, own.heights, one.heights), np.where(mine, 0, one.ring)),
    ]


def simulated() -> None:
    """The rules on the simulated scenes (studies/dense_cell_precision's cloud: the truth's models): the own cells'
    share of the evaluation cells and the 10 m DSM minus the true DSM, RMS by class."""
    for name, config in SCENES.items():
        paths = simulate_scene(config, tempfile.mkdtemp() + "/scene")
        truth = Truth(paths)
        c = cloud(paths, truth)
        grid, i, j = evaluation_grid(truth)
        zones = {label: truth.cls == k for k, label in CLASSES.items()}
        zones.update({"building edges": truth.edge, "open near": truth.near})
        print(f"\n{name}\n| rule | own cells | " + " | ".join(zones) + " |\n|" + "---|" * (2 + len(zones)))
        for rule, (heights, ring) in zip(
            ("the DEM step's (the precision rule)", "the tier alone", "own points first"),
            the_rules(c["x"], c["y"], c["z"], c["sigma"], grid, c["tier"]),
        ):
            dh = heights[i, j] - truth.h
            own = 100 * (ring[i, j] == 0).mean()
            row = " | ".join(f"{rms(dh[m & np.isfinite(dh)]):.2f}" for m in zones.values())
            print(f"| {rule} | {own:.1f} % | {row} |")


if __name__ == "__main__":
    main()
