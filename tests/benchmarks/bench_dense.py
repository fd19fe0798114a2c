"""Dense matching per stage and per core (algorithms/dense): one 512 px tile of the Pleiades triplet
(img_02 -> img_01, its RPCs, heights 40-535 m), numba on 1 thread: epipolar resampling (grid and both
images, per epipolar pixel), census cost and semi-global aggregation (libsgm; per epipolar pixel, over the
disparity range the tile's seeds narrow it to, as pair_tile.match_pair_tile does), the seeds themselves (NCC along
the height range's path, then LSM: per tile pixel), LSM refinement of every
matched pixel (per node tried), triangulation (per point) and the per-cell rasterization at 0.5 m with the DEM
step's default radius (per point).
Best of three after a warm-up."""

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense.epipolar import epipolar_grid
from pushbroom.algorithms.dense.pair_tile import match_pair_tile, tile_seeds
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.refine import Conjugates, refine_positions
from pushbroom.algorithms.dense.resample import epipolar_image
from pushbroom.algorithms.dense.sgm import disparity
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.resolution import adapt_resolution
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_dem import DemParams
from pushbroom.algorithms.surface.tin_grid import Grid
from tests.benchmarks.benchutil import SHARED_DATA, best_time, thread_counts

BOX = (256, 256, 768, 768)
HEIGHTS = (40.0, 535.0)


def run():
    folder = SHARED_DATA / "pleiades_triplet"
    if not folder.exists():
        return [{"stage": f"skipped: no {folder}"}]
    paths = [folder / "img_02.tif", folder / "img_01.tif"]
    models = [sensors.load(p) for p in paths]
    images = [Image(p) for p in paths]
    params = DenseParams()
    rows = []
    for _ in thread_counts((1,)):
        a1, a2 = adapt_resolution(images[0], images[1], models[0], models[1], GrowParams(), HEIGHTS)
        margin = params.sgm.census_radius + 2

        def resample():
            grid = epipolar_grid(models[0], models[1], BOX, HEIGHTS, step=params.grid_step, margin=margin)
            return grid, epipolar_image(a1, grid.p, grid.step), epipolar_image(a2, grid.q, grid.step)

        grid, epi1, epi2 = resample()
        pixels = epi1.size
        rows.append(
            {
                "stage": "epipolar resampling (grid, 2 images)",
                "items": pixels,
                "per second": pixels / best_time(resample),
                "unit": "epipolar px",
            }
        )
        x1, y1, x2, y2, info = match_pair_tile(images[0], images[1], models[0], models[1], BOX, HEIGHTS, params)
        # the tile's seeds: NCC along each Foerstner point's path over the whole height range, then LSM (the kernels
        # of the terrain height search too)
        tile_px = (BOX[2] - BOX[0]) * (BOX[3] - BOX[1])
        seconds = best_time(lambda: tile_seeds(images[0], images[1], models[0], models[1], BOX, HEIGHTS, grid))
        rows.append(
            {
                "stage": f"seeds (NCC along {HEIGHTS[0]:g}-{HEIGHTS[1]:g} m, LSM: {info['seeds']} found)",
                "items": tile_px,
                "per second": tile_px / seconds,
                "unit": "tile px",
            }
        )
        d_range = info["d_range"]
        seconds = best_time(lambda: disparity(epi1, epi2, d_range, params.sgm))
        rows.append(
            {
                "stage": f"census + SGM + WTA + LR check ({d_range[1] - d_range[0] + 1} disparities)",
                "items": pixels,
                "per second": pixels / seconds,
                "unit": "epipolar px",
            }
        )
        ok = np.isfinite(x2)
        x1, y1, x2, y2 = x1[ok], y1[ok], x2[ok], y2[ok]
        refined = refine_positions(
            ImagePair(images[0], images[1], models[0], models[1]),
            Conjugates(x1, y1, x2, y2),
            info["grid"].heights[::2],
            params.refinement(),
        )
        seconds = best_time(
            lambda: refine_positions(
                ImagePair(images[0], images[1], models[0], models[1]),
                Conjugates(x1, y1, x2, y2),
                info["grid"].heights[::2],
                params.refinement(),
            )
        )
        kind = "robust" if params.robust else "plain"
        rows.append(
            {
                "stage": f"LSM refinement, {kind} ({100 * np.isfinite(refined.rho).mean():.0f} % accepted)",
                "items": x1.size,
                "per second": x1.size / seconds,
                "unit": "nodes",
            }
        )
        n = x1.size
        rx, ry = refined[0], refined[1]

        def triangulate():
            return intersection.intersect_measured(models[:2], [x1, rx], [y1, ry])

        result = triangulate()
        rows.append(
            {"stage": "triangulation (2 rays)", "items": n, "per second": n / best_time(triangulate), "unit": "points"}
        )
        good = result.ok
        srs = output_srs(None, result.lon[good], result.lat[good])
        x, y = reproject(result.lon[good], result.lat[good], wgs84(), srs)
        grid = Grid.covering(x, y, 0.5)
        radius = DemParams().radius
        seconds = best_time(lambda: cells_on_grid(x, y, result.h[good], None, grid, CellSettings(radius=radius)))
        rows.append(
            {
                "stage": f"per-cell rasterization (0.5 m, radius {radius})",
                "items": int(good.sum()),
                "per second": good.sum() / seconds,
                "unit": "points",
            }
        )
    return rows


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    print(markdown_table(run()))
