"""Issue 39: can 95 % of the Pleiades triplet's 0.5 m cells hold a point of their own, with one point per pixel?

The triplet (img_02, img_01, img_03; ../shared/data) matched densely (default DenseParams, 2 threads, 40-535 m), its
points intersected with the supplied RPCs. A cell "holds a point of its own" as the DEM step counts it (cell_dem.py,
mask 0): a point falls inside it. On grids of several cell sizes in the points' UTM zone, over the cells whose centre
every image sees (the footprint, as make bench-peers), this counts the share of cells that hold:
- refined: a refined point (rho_min finite: the points interpolatedem uses with FALLBACK off);
- every point: any matched point;
- the DEM step's own cells: mask 0 of the per-cell DSM (cell_dem.cells_on_grid: k 3, FALLBACK off, RADIUS 1, the
  points' tiers), where the tier comes before the ring: a cell whose own points are two-ray takes a three-ray
  point of the ring around, and is not counted as own;
- every pixel: a pixel centre of img_02, the reference, each projected to the ground (RpcModel.image_to_ground) at
  its point's height where the node matched, else at the height of the nearest matched node in the image. This is
  what a lattice of one point per pixel, every node matched and refined, could give at best: the floor the
  sampling sets, whatever the matching does.

Cells the size of the pixel hold a point of their own only where the projected lattice puts one in them; the lattice
is sheared and stretched on the ground by the view angle and the slopes, so some cells get two and some none."""

import tempfile

import numpy as np
from scipy import ndimage

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid, point_tiers
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from studies.sim_dense import SHARED
from tests.helpers.real_dsm import dense_points, footprint_mask

FILES = [SHARED / "pleiades_triplet" / f"img_0{k}.tif" for k in (2, 1, 3)]  # the reference first
HEIGHTS = (40.0, 535.0)
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
    if not all(f.exists() for f in FILES):
        print(f"the Pleiades triplet is not in {SHARED}")
        return
    models = [sensors.load(f) for f in FILES]
    points, _ = dense_points(FILES, models, ["img_02", "img_01", "img_03"], tempfile.mkdtemp(), HEIGHTS)
    obs = points.observations
    res = intersect(
        {k + 1: m for k, m in enumerate(models)}, Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"])
    )
    ok = res.ok
    slot = np.searchsorted(points.points["id"], res.point[ok])
    refined = np.isfinite(points.points["rho_min"][slot])
    tier = point_tiers(points.points["rho_min"][slot], res.rays[ok])
    lon, lat, h = res.lon[ok], res.lat[ok], res.h[ok]
    srs = output_srs(None, lon, lat)
    x, y = reproject(lon, lat, wgs84(), srs)
    # every pixel centre of the reference at its node's height, or the nearest matched node's
    ref = obs[obs["image_id"] == 1]
    at = {int(p): (c, r) for p, c, r in zip(ref["point_id"], ref["col"], ref["row"])}
    cols, rows = models[0].size
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
        "| cell (m) | footprint cells | pixels per cell | refined | the DEM step's own cells | every point "
        "| every pixel (the floor) |"
    )
    print("|---|---|---|---|---|---|---|")
    for cell in CELLS:
        x0, y1 = np.floor(px.min() / cell) * cell, np.ceil(py.max() / cell) * cell
        grid = Grid(x0, y1, cell, int(np.ceil((px.max() - x0) / cell)), int(np.ceil((y1 - py.min()) / cell)))
        inside = footprint_mask(grid, srs, models, float(np.median(h)))
        shares = [held(grid, inside, a, b)[0] for a, b in ((x[refined], y[refined]), (x, y), (px, py))]
        cells = cells_on_grid(x, y, h, None, grid, CellSettings(k=3.0, fallback=False, radius=1), tier=tier)
        shares.insert(1, float((cells.ring == 0)[inside].mean()))
        print(
            f"| {cell:g} | {int(inside.sum())} | {held(grid, inside, px, py)[1]:.2f} | "
            + " | ".join(f"{100 * s:.1f} %" for s in shares)
            + " |"
        )


if __name__ == "__main__":
    main()
