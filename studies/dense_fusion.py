"""Which dense points should a DSM cell trust? On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the
DSM's height range +- 100 m), dense matching (algorithms/dense, default DenseParams but 256 px tiles), every
point intersected with the TRUE models (so the error is the
matching's alone), the points' height error against the true DSM by class and by refinement (LSM accepted
or the semi-global position kept), then 10 m DSMs (cell_dem.cells_on_grid, per-cell medians) against the
true DSM at the cell centres, by class: from every point; from the refined points only; refined where a
cell has one, else the unrefined; refined, with the other cells filled by linear interpolation (Delaunay)
of the refined cells; and on the cells so filled, the fill against the unrefined points' median. Last, the
product's way (surface/dem_tiles.py, method "cells"): the cloud as a LAS with its rho, per-cell medians of
each cell's best tier, with and without the unrefined fallback, the gaps filled within FILL cells by GDAL
(gap_fill.py)."""

import tempfile
import time

import numpy as np
from osgeo import gdal
from scipy.interpolate import griddata

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.cell_dem import cells_on_grid
from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
from pushbroom.algorithms.surface.pointcloud import output_srs, write_las
from pushbroom.algorithms.surface.tin_dem import DemParams
from pushbroom.algorithms.surface.tin_grid import Grid

NAMES = ("HRG", "HRS1", "HRS2")
CLASSES = {2: "bare", 3: "crops", 4: "forest", 5: "city"}
CELL = 10.0
FILL = 10.0  # cells: the gap filling's reach


def rms(v):
    return float(np.sqrt(np.mean(np.square(v)))) if np.size(v) else float("nan")


def class_at(classes, lon, lat):
    gt, values = classes.GetGeoTransform(), classes.ReadAsArray()
    i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, values.shape[0] - 1)
    j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, values.shape[1] - 1)
    return values[i, j]


def row(label, heights, ref, cls):
    d = heights - ref
    out = f"  {label:34} cells {np.isfinite(heights[np.isfinite(ref) & (cls != 1)]).mean():6.1%}"
    return out + "".join(f" | {name} {rms(d[(cls == k) & np.isfinite(d)]):5.2f}" for k, name in CLASSES.items())


def study(paths):
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    truth = {k: sensors.load(paths["truth_metadata"][n]) for k, n in enumerate(NAMES, start=1)}
    dsm = read_dem(paths["dsm"])
    lo, hi = dsm.height_range
    t = time.perf_counter()
    parts, stats = match_dense_tiles(
        images,
        models,
        tempfile.mkdtemp() + "/dense",
        params=DenseParams(tile=256),
        height_range=(lo - 100.0, hi + 100.0),
        execution=Execution("threads", 2),
    )
    print(f"{stats['points']} points, {stats['refined']} image positions refined, {time.perf_counter() - t:.0f} s")
    pts = np.concatenate([p.points for p in parts])
    obs = np.concatenate([p.observations for p in parts])
    res = intersection.intersect(
        truth, intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]), h0=0.5 * (lo + hi)
    )
    ok = res.ok
    lon, lat, z = res.lon[ok], res.lat[ok], res.h[ok]
    refined = np.isfinite(pts["rho_min"][np.searchsorted(pts["id"], res.point[ok])])
    classes = gdal.Open(str(paths["classes"]))
    cls = class_at(classes, lon, lat)
    dh = z - dsm.height(lon, lat)
    for k, name in CLASSES.items():
        print(
            f"  points on {name:6}: refined {np.mean(refined[cls == k]):5.1%}, RMS refined "
            f"{rms(dh[(cls == k) & refined]):5.2f} m, unrefined {rms(dh[(cls == k) & ~refined]):5.2f} m"
        )
    srs = output_srs(None, lon, lat)
    x, y = reproject(lon, lat, wgs84(), srs)
    x0, y0 = np.floor(x.min() / CELL) * CELL, np.ceil(y.max() / CELL) * CELL
    grid = Grid(float(x0), float(y0), CELL, int((x.max() - x0) // CELL) + 1, int((y0 - y.min()) // CELL) + 1)
    cx, cy = grid.centres()
    clon, clat = reproject(cx.ravel(), cy.ravel(), srs, wgs84())
    ref = dsm.height(clon, clat).reshape(grid.shape)
    ccls = class_at(classes, clon, clat).reshape(grid.shape)
    every = cells_on_grid(x, y, z, None, grid)[0]
    best = cells_on_grid(x[refined], y[refined], z[refined], None, grid)[0]
    print("  10 m DSM against the true DSM, RMS (m):")
    print(row("every point", every, ref, ccls))
    print(row("refined points", best, ref, ccls))
    print(row("refined, else unrefined", np.where(np.isfinite(best), best, every), ref, ccls))
    have = np.nonzero(np.isfinite(best))
    gaps = np.nonzero(np.isfinite(every) & ~np.isfinite(best))
    filled = best.copy()
    filled[gaps] = griddata(have, best[have], gaps, method="linear")
    print(row("refined, the others interpolated", filled, ref, ccls))
    only = np.full(grid.shape, np.nan)
    only[gaps] = filled[gaps]
    print(row("  the interpolated cells", only, ref, ccls))
    only[gaps] = every[gaps]
    print(row("  the same cells, unrefined points", only, ref, ccls))
    folder = tempfile.mkdtemp()
    rho = pts["rho_min"][np.searchsorted(pts["id"], res.point[ok])]
    write_las(folder + "/dense.las", x, y, z, {"rho": rho.astype(np.float32)}, srs)
    for label, fallback, fill in (
        ("interpolatedem: best tier", True, 0.0),
        ("interpolatedem: refined only", False, 0.0),
        (f"interpolatedem: refined, filled within {FILL:g}", False, FILL),
    ):
        out = f"{folder}/dem-{fallback}-{fill:g}.tif"
        dem = dem_from_point_cloud(
            folder + "/dense.las", out, DemParams(cell=CELL, method="cells", fallback=fallback, fill=fill)
        )
        ds = gdal.Open(out)
        heights = ds.ReadAsArray().astype(float)
        heights[heights == ds.GetRasterBand(1).GetNoDataValue()] = np.nan
        dx, dy = dem.grid.centres()
        dlon, dlat = reproject(dx.ravel(), dy.ravel(), srs, wgs84())
        print(
            row(
                label,
                heights,
                dsm.height(dlon, dlat).reshape(dem.grid.shape),
                class_at(classes, dlon, dlat).reshape(dem.grid.shape),
            )
        )


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    study(paths)


if __name__ == "__main__":
    main()
