"""A wider second LSM window in the dense refinement: does it measure the cells the default template leaves?

On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the supplied models, the DSM's height range +- 100 m),
dense matching (algorithms/dense, default DenseParams but 256 px tiles) with DenseParams.wide_template off
and at WIDES px; every point intersected with the TRUE models (so the error is the matching's alone). Per
setting: the points refined, the matching time, then the product's 10 m DSM of the cloud (surface/dem_tiles.py,
method "cells", FALLBACK off, RADIUS 1, FILL 10: the dense pipeline model's) against the true DSM at the cell
centres by class (the classes of tests/helpers/dsm_comparison.py), and the share of the non-water cells from
their own points (mask 0), from the cells around (2) and filled (1). Then, where ../shared/data holds it, the
Pleiades triplet (img_02 the reference, over the terrain's heights 40 to 535 m, 2 threads): the dense points
refined (in every position) and the matching time per setting, twice each, alternating."""

import tempfile
import time

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
from pushbroom.algorithms.surface.pointcloud import write_las
from pushbroom.algorithms.surface.tin_dem import DemParams
from tests.benchmarks.benchutil import SHARED_DATA
from tests.helpers.dsm_comparison import CELL, NAMES, Truth

WIDES = (0, 31)
FILL = 10.0


def rms(v):
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


def at_cells(path, truth):
    """The raster `path` at the evaluation cells of `truth` (NaN: outside or nodata)."""
    ds = gdal.Open(path)
    gt, values = ds.GetGeoTransform(), ds.ReadAsArray().astype(float)
    nodata = ds.GetRasterBand(1).GetNoDataValue()
    if nodata is not None:
        values[values == nodata] = np.nan
    j, i = np.floor((truth.x - gt[0]) / gt[1]).astype(int), np.floor((truth.y - gt[3]) / gt[5]).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < values.shape[0]) & (j < values.shape[1])
    out = np.full(truth.x.size, np.nan)
    out[inside] = values[i[inside], j[inside]]
    return out


def one(paths, truth, wide):
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    lo, hi = read_dem(paths["dsm"]).height_range
    t = time.perf_counter()
    parts, stats = match_dense_tiles(
        images,
        models,
        tempfile.mkdtemp() + "/dense",
        params=DenseParams(tile=256, wide_template=wide),
        height_range=(lo - 100.0, hi + 100.0),
        execution=Execution("threads", 2),
    )
    seconds = time.perf_counter() - t
    pts = np.concatenate([p.points for p in parts])
    obs = np.concatenate([p.observations for p in parts])
    res = intersection.intersect(
        truth.models,
        intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]),
        h0=0.5 * (lo + hi),
    )
    ok = res.ok
    x, y = reproject(res.lon[ok], res.lat[ok], wgs84(), truth.srs)
    slot = np.searchsorted(pts["id"], res.point[ok])
    folder = tempfile.mkdtemp()
    fields = {"rho": pts["rho_min"][slot].astype(np.float32), "rays": res.rays[ok].astype(np.uint8)}
    write_las(folder + "/dense.las", x, y, res.h[ok], fields, truth.srs)
    out, mask = folder + "/dem.tif", folder + "/mask.tif"
    dem_from_point_cloud(
        folder + "/dense.las",
        out,
        DemParams(cell=CELL, method="cells", fallback=False, fill=FILL, radius=1),
        mask_path=mask,
    )
    dh = at_cells(out, truth) - truth.h
    source = at_cells(mask, truth)[~truth.water]
    table = truth.table(dh, np.isfinite(dh))
    refined = np.isfinite(pts["rho_min"]).mean()
    print(
        f"wide template {wide or 'off'}: {stats['points']} points, {refined:.1%} refined, matching {seconds:.0f} s; "
        f"non-water cells: own points {np.mean(source == 0):.1%}, the cells around {np.mean(source == 2):.1%}, "
        f"filled {np.mean(source == 1):.1%}"
    )
    print("   10 m DSM - true DSM, RMS: " + ", ".join(f"{zone} {v[2]:.2f} m" for zone, v in table.items()))


def pleiades():
    images = [SHARED_DATA / "pleiades_triplet" / f"img_0{k}.tif" for k in (2, 1, 3)]
    if not all(p.exists() for p in images):
        print(f"{images[0].parent} is absent: no Pleiades run")
        return
    models = [sensors.load(str(p)) for p in images]
    for wide in WIDES + WIDES:
        t = time.perf_counter()
        parts, _ = match_dense_tiles(
            [str(p) for p in images],
            models,
            tempfile.mkdtemp() + "/dense",
            names=["two", "one", "three"],
            params=DenseParams(wide_template=wide),
            height_range=(40.0, 535.0),
            execution=Execution("threads", 2),
        )
        seconds = time.perf_counter() - t
        rho = np.concatenate([p.points["rho_min"] for p in parts])
        print(
            f"Pleiades triplet, wide template {wide or 'off'}: {rho.size} points, "
            f"{np.isfinite(rho).mean():.1%} refined, {seconds:.0f} s"
        )


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    for wide in WIDES:
        one(paths, truth, wide)
    pleiades()


if __name__ == "__main__":
    main()
