"""`make bench-peers`: Pushbroom's dense chain against CNES CARS 1.3.0 on the real Pleiades triplet, one
after the other in the same run (not in CI).

Pushbroom, each step one `qgis_process run` with 2 threads: createblock (no DEM, no height: the range is found
by matching), matchpoints (STRATEGY 2, dense, every pixel of img_02), intersectpoints, interpolatedem
(per-cell medians of the refined points at 0.5 m, FALLBACK off). CARS 1.3.0 from its own venv
(build/peers/cars, numpy 2; `make bench-peers` installs it), the same three images with the RPCs of their
GeoTIFFs, pairs img_02-img_01 and img_02-img_03, 0.5 m, its default orchestrator. Printed: each tool's time
and peak memory (the sum of the processes' VmHWM), the ratio of the times, each DSM's coverage of the cells
whose centre lies in all three images (at the median height), and Pushbroom's DSM minus CARS's (GDAL warps
CARS's onto Pushbroom's grid) where both are defined. The simulated triplet (CARS reading RPCs fitted by
pushbroom:fitrpc) is not in it yet.

    .venv/bin/python -m scripts.bench_peers
"""
import json
import os
import pathlib
import sys
import tempfile

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.surface.tin_grid import Grid
from tests.benchmarks.bench_chain_memory import measured
from tests.benchmarks.benchutil import SHARED_DATA
from tests.benchmarks.run_all import markdown_table
from tests.helpers.qgis_process_profile import QGIS_PROCESS, REPO, qgis_process_env
from tests.helpers.real_dsm import footprint_mask

DATA = SHARED_DATA / "pleiades_triplet"
IMAGES = [DATA / f"img_0{k}.tif" for k in (2, 1, 3)]       # the reference first, as both tools pair them
CARS = REPO / "build" / "peers" / "cars" / "bin" / "cars"
WORKERS = 2


def pushbroom(out):
    """(rows, DEM path) of Pushbroom's dense chain."""
    block, cloud, dem = out / "block.gpkg", out / "points.las", out / "dem.tif"
    tiled = ["EXECUTION=0", f"WORKERS={WORKERS}"]
    steps = [("createblock", ["pushbroom:createblock", "--", *(f"IMAGES={p}" for p in IMAGES), f"OUTPUT={block}"]),
             ("matchpoints (dense)", ["pushbroom:matchpoints", "--", f"BLOCK={block}", "STRATEGY=2", *tiled]),
             ("intersectpoints", ["pushbroom:intersectpoints", "--", f"BLOCK={block}", "POINTS=0", *tiled,
                                  f"OUTPUT={cloud}"]),
             ("interpolatedem (per cell, 0.5 m)", ["pushbroom:interpolatedem", "--", f"INPUT={cloud}", "CELL=0.5",
                                                   "METHOD=1", "FALLBACK=false", *tiled, f"OUTPUT={dem}"])]
    env = qgis_process_env(out / "profile")
    rows = []
    for name, args in steps:
        seconds, peak, _, _ = measured([QGIS_PROCESS, "run"] + args, env)
        print(f"  Pushbroom {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
        rows.append({"tool": "Pushbroom", "step": name, "seconds": seconds, "peak MB": peak})
    return rows, dem


def cars(out):
    """(rows, DSM path) of CARS on the triplet."""
    conf = out / "cars.json"
    names = ("one", "two", "three")
    conf.write_text(json.dumps({
        "input": {"sensors": {n: {"image": str(p)} for n, p in zip(names, IMAGES)},
                  "pairing": [["one", "two"], ["one", "three"]]},
        "output": {"directory": str(out / "cars"), "resolution": 0.5}}))
    seconds, peak, _, output = measured([str(CARS), "--logtype", "plain", str(conf)], dict(os.environ))
    dsm = out / "cars" / "dsm" / "dsm.tif"
    if not dsm.exists():
        sys.exit(f"CARS made no DSM:\n{output[-3000:]}")
    print(f"  CARS: {seconds:.1f} s, {peak:.0f} MB", flush=True)
    return [{"tool": "CARS 1.3.0", "step": "whole pipeline", "seconds": seconds, "peak MB": peak}], dsm


def band(ds):
    values = ds.GetRasterBand(1).ReadAsArray().astype(float)
    nodata = ds.GetRasterBand(1).GetNoDataValue()
    if nodata is not None:
        values[values == nodata] = np.nan
    return values


def compare(dem, dsm):
    """Rows: each DSM's coverage of the common footprint on Pushbroom's grid, and their difference."""
    ds = gdal.Open(str(dem))
    gt, cols, rows = ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize
    ours = band(ds)
    warped = gdal.Warp("", str(dsm), format="MEM", dstSRS=ds.GetProjection(), outputType=gdal.GDT_Float32,
                       outputBounds=(gt[0], gt[3] + rows * gt[5], gt[0] + cols * gt[1], gt[3]), width=cols,
                       height=rows, resampleAlg="bilinear", dstNodata=np.nan)
    theirs = band(warped)
    srs = ds.GetSpatialRef()
    models = [sensors.load(p) for p in IMAGES]
    inside = footprint_mask(Grid(gt[0], gt[3], gt[1], cols, rows), srs, models, float(np.nanmedian(ours)))
    diff = summarize((ours - theirs)[inside & np.isfinite(ours) & np.isfinite(theirs)])
    return [{"tool": "Pushbroom", "step": "coverage of the common footprint",
             "value": f"{100 * np.isfinite(ours[inside]).mean():.1f} %"},
            {"tool": "CARS 1.3.0", "step": "coverage of the common footprint",
             "value": f"{100 * np.isfinite(theirs[inside]).mean():.1f} %"},
            {"tool": "Pushbroom - CARS", "step": "DSM differences where both are defined",
             "value": f"N {diff.n}, median {diff.median:+.3f} m, NMAD {diff.nmad:.3f} m, RMS {diff.rms:.3f} m"}]


def run():
    if not DATA.is_dir():
        sys.exit(f"{DATA} is absent")
    if not CARS.exists():
        sys.exit(f"{CARS} is missing: run make bench-peers, which installs CARS 1.3.0 into build/peers/cars")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        ours, dem = pushbroom(tmp)
        theirs, dsm = cars(tmp)
        total = sum(r["seconds"] for r in ours)
        rows = ours + [{"tool": "Pushbroom", "step": "total", "seconds": total}] + theirs
        rows.append({"tool": "CARS / Pushbroom", "step": "time ratio",
                     "value": f"{theirs[0]['seconds'] / total:.2f}"})
        rows += compare(dem, dsm)
    return [{k: r.get(k, "") for k in ("tool", "step", "seconds", "peak MB", "value")} for r in rows]


if __name__ == "__main__":
    print(markdown_table(run()))
