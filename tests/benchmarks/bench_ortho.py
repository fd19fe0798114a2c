"""Orthorectification with an RPC model: pushbroom.ortho against gdalwarp -rpc -to RPC_DEM=... in the same run.

The small simulated scene's HRG image (600 x 599 px, 5 m) with an RPC fitted to its truth model, written as
_RPC.TXT beside a copy of the image (so GDAL reads the same RPC), on the true DSM (EPSG:4326 grid,
ellipsoidal heights); the output is the same UTM grid of 1.25 m cells (about 2400 x 2400) for both, bilinear,
tiled DEFLATE GeoTIFF without overviews, 1 and 2 threads (gdalwarp -multi -wo NUM_THREADS=n). gdalwarp runs
with its default approximate transformer (-et 0.125 px); ours with its default bound of 0.01 px. Agreement:
our per-cell image points against GDAL's exact RPC transformer (RPC_DEM, bilinear DEM) on the same cells, and
the DN difference of the two outputs where both have values. Best of 3 after a warm-up."""

import os
import shutil
import tempfile

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.ortho import OrthoSettings, default_grid, orthorectify
from pushbroom.algorithms.ortho.mapping import TileMapper
from pushbroom.algorithms.ortho.orthorectify import CREATION_OPTIONS
from pushbroom.algorithms.sensors.rpc_fit import fit_rpc, rpc_txt_path, write_fitted_rpc
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.benchmarks.benchutil import best_time

CELL = 1.25


def prepare(folder):
    """(image with GDAL-readable RPC, its RpcModel, DSM path, Dem, OutputGrid)."""
    paths = simulate_scene(SceneConfig.small(), os.path.join(folder, "scene"))
    truth = sensors.load(paths["truth_metadata"]["HRG"])
    dem = read_dem(paths["dsm"])
    lo, hi = dem.height_range
    rpc, _ = fit_rpc(truth, (lo - 100.0, hi + 100.0))
    image = os.path.join(folder, "hrg.tif")
    shutil.copy(paths["images"]["HRG"]["imagery"], image)
    write_fitted_rpc(rpc, rpc_txt_path(image))
    model = sensors.load(image)
    return image, model, paths["dsm"], dem, default_grid(model, dem, cell_size=CELL)


def gdal_warp(image, dsm, grid, output, threads):
    x0, dx, _, y0, _, dy = grid.geotransform
    return gdal.Warp(
        output,
        image,
        format="GTiff",
        outputBounds=(x0, y0 + grid.rows * dy, x0 + grid.cols * dx, y0),
        width=grid.cols,
        height=grid.rows,
        dstSRS=grid.srs.ExportToWkt(),
        resampleAlg="bilinear",
        rpc=True,
        transformerOptions=[f"RPC_DEM={dsm}"],
        multithread=threads > 1,
        warpOptions=[f"NUM_THREADS={threads}"],
        dstNodata=0,
        creationOptions=list(CREATION_OPTIONS),
    )


def image_point_agreement(image, model, dsm, dem, grid, window=(800, 800, 512, 512)):
    """Largest and RMS distance (px) of our image points from GDAL's exact RPC transformer on a window of cells."""
    row0, col0, rows, cols = window
    tile = TileMapper(model, dem, grid).tile(row0, col0, rows, cols)
    target = gdal.GetDriverByName("MEM").Create("", grid.cols, grid.rows, 1)
    target.SetGeoTransform(grid.geotransform)
    target.SetSpatialRef(grid.srs)
    transformer = gdal.Transformer(gdal.Open(image), target, ["METHOD=RPC", f"RPC_DEM={dsm}"])
    i, j = np.mgrid[row0 : row0 + rows, col0 : col0 + cols]
    pts, ok = transformer.TransformPoints(1, np.column_stack([j.ravel() + 0.5, i.ravel() + 0.5]))
    pts = np.asarray(pts)
    d = np.hypot(tile.col.ravel() - pts[:, 0], tile.row.ravel() - pts[:, 1])[np.asarray(ok, bool)]
    d = d[np.isfinite(d)]
    return float(d.max()), float(np.sqrt(np.mean(d**2))), tile.bound


def run():
    gdal.UseExceptions()
    folder = tempfile.mkdtemp(prefix="bench_ortho.")
    try:
        image, model, dsm, dem, grid = prepare(folder)
        ours_path, gdal_path = os.path.join(folder, "ours.tif"), os.path.join(folder, "gdal.tif")
        worst, rms, bound = image_point_agreement(image, model, dsm, dem, grid)
        rows = []
        for threads in (1, 2):
            t_ours = best_time(
                lambda: orthorectify(
                    image,
                    model,
                    dem,
                    ours_path,
                    grid=grid,
                    settings=OrthoSettings(overviews=False),
                    execution=Execution("threads", threads),
                )
            )
            t_gdal = best_time(lambda: gdal_warp(image, dsm, grid, gdal_path, threads))
            a = gdal.Open(ours_path).ReadAsArray().astype(float)
            b = gdal.Open(gdal_path).ReadAsArray().astype(float)
            both = (a > 0) & (b > 0)
            rows.append(
                {
                    "threads": threads,
                    "cells": f"{grid.cols} x {grid.rows}",
                    "pushbroom s": t_ours,
                    "gdalwarp s": t_gdal,
                    "gdalwarp / pushbroom": t_gdal / t_ours,
                    "our bound px": bound,
                    "max |ours - GDAL RPC| px": worst,
                    "RMS px": rms,
                    "mean |dDN|": float(np.abs(a - b)[both].mean()),
                    "valid cells ours / GDAL": float(np.count_nonzero(a > 0) / max(np.count_nonzero(b > 0), 1)),
                }
            )
        return rows
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    for r in run():
        print("  ".join(f"{k}: {v:.4g}" if isinstance(v, float) else f"{k}: {v}" for k, v in r.items()))
