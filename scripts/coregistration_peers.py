"""`make bench-xdem`: Pushbroom's co-registration (algorithms/quality/coregistration.py, Nuth and Kääb 2011) against
xdem's NuthKaab on the same DEMs (not in CI). xdem 0.2.3 runs in its own venv (build/peers/xdem; it needs the pyogrio
and rasterio wheels, each with a GDAL of its own, which must never load into QGIS's process), through
scripts/xdem_nuth_kaab.py; Pushbroom in this process.

Three cases, each a DEM made from a surface at cells moved by a known shift (its grid's origin moved: no height is
resampled), raised by a known offset, with noise:
- an analytic terrain (tests/helpers/dem_shift.py's, as the tests'), 10 m cells;
- the simulated scene's true DSM (SceneConfig.small()), warped to UTM at 10 m with the exact transformation, the
  forest, town and water masked by the simulator's classes;
- SRTM over Mont Ventoux (../shared/data/pleiades_pair_ventoux/N44E005.hgt), warped to UTM at 90 m, 36 km a side.
xdem is given the reference on the DEM's grid (gdalwarp, average or cubic, exact) and the stable cells there;
Pushbroom the reference as it is. Printed: the truth, each tool's shift, their difference in cells (issue 40 asks
0.05 cell), each tool's time.

    .venv/bin/python -m scripts.coregistration_peers
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import crs
from pushbroom.algorithms.quality.coregistration import CoregParams, coregister
from pushbroom.algorithms.quality.height_differences import Reference
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface.geotiff import write_float_raster
from tests.benchmarks.benchutil import SHARED_DATA
from tests.benchmarks.run_all import markdown_table
from tests.helpers.dem_shift import CELL, ORIGIN, UTM, centres, terrain, unstable_mask, warped_dsm
from tests.helpers.qgis_process_profile import REPO

XDEM = REPO / "build" / "peers" / "xdem" / "bin" / "python"
SHIFT, UP = (7.3, -4.1), 2.2


def moved(values: np.ndarray, gt: tuple, srs, path: pathlib.Path, shift, up: float, noise: float) -> str:
    """The heights `values` of the grid `gt` with their cells moved by -shift (DEM(x) = surface(x + shift)), `up`
    higher, with `noise` m of noise."""
    heights = values + up + np.random.default_rng(7).normal(0.0, noise, values.shape)
    origin = (gt[0] - shift[0], gt[3] - shift[1])
    return str(write_float_raster(str(path), heights, (origin[0], gt[1], 0, origin[1], 0, gt[5]), srs))


def analytic(folder: pathlib.Path) -> dict:
    x, y = centres(ORIGIN, 300)
    gt = (ORIGIN[0], CELL, 0, ORIGIN[1], 0, -CELL)
    utm = crs.srs(UTM)
    reference = str(write_float_raster(str(folder / "analytic_ref.tif"), terrain(x, y), gt, utm))
    dem = moved(terrain(x, y)[20:270, 20:270], _window(gt, 20, 20), utm, folder / "analytic.tif", SHIFT, UP, 0.5)
    return {"case": "analytic terrain, 10 m, 0.5 m noise", "reference": reference, "dem": dem, "mask": None}


def _window(gt: tuple, col: int, row: int) -> tuple:
    return (gt[0] + col * gt[1], gt[1], 0.0, gt[3] + row * gt[5], 0.0, gt[5])


def simulated(folder: pathlib.Path) -> dict:
    paths = simulate_scene(SceneConfig.small(), str(folder / "scene"))
    values, gt, srs = warped_dsm(paths["dsm"], folder / "dsm_utm.tif", 10.0, 32616)
    dem = moved(values, gt, srs, folder / "simulated.tif", SHIFT, UP, 0.3)
    mask = unstable_mask(paths["classes"], folder / "unstable.tif")
    return {
        "case": "simulated true DSM, 10 m, 0.3 m noise, forest/town/water masked",
        "reference": paths["dsm"],
        "dem": dem,
        "mask": mask,
    }


def srtm(folder: pathlib.Path) -> dict:
    hgt = SHARED_DATA / "pleiades_pair_ventoux" / "N44E005.hgt"
    bounds = (660_000.0, 4_870_000.0, 696_000.0, 4_906_000.0)
    values, gt, srs = warped_dsm(hgt, folder / "srtm_utm.tif", 90.0, 32631, bounds)
    reference = str(folder / "srtm_utm.tif")
    dem = moved(values, gt, srs, folder / "srtm_moved.tif", (37.3, -24.1), UP, 1.0)
    return {
        "case": 'SRTM 3" over Mont Ventoux, 90 m, 1 m noise',
        "reference": reference,
        "dem": dem,
        "mask": None,
        "shift": (37.3, -24.1),
    }


def for_xdem(case: dict, folder: pathlib.Path) -> tuple[str, str | None]:
    """The reference on the DEM's grid (average where finer, else cubic; exact) and the stable cells there."""
    ds = gdal.Open(case["dem"])
    gt, cols, rows = ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize
    bounds = (gt[0], gt[3] + rows * gt[5], gt[0] + cols * gt[1], gt[3])
    reference = folder / f"{pathlib.Path(case['dem']).stem}_ref_on_grid.tif"
    common = dict(
        dstSRS=ds.GetProjection(),
        width=cols,
        height=rows,
        outputBounds=bounds,
        errorThreshold=0,
        dstNodata=-9999,
        outputType=gdal.GDT_Float32,
    )
    gdal.Warp(str(reference), case["reference"], resampleAlg="average" if case["mask"] else "cubic", **common)
    if not case["mask"]:
        return str(reference), None
    stable = folder / f"{pathlib.Path(case['dem']).stem}_stable.tif"
    gdal.Warp(
        str(stable), case["mask"], resampleAlg="near", **{**common, "outputType": gdal.GDT_Byte, "dstNodata": 255}
    )
    ds = gdal.Open(str(stable), gdal.GA_Update)
    band = ds.GetRasterBand(1)
    band.WriteArray((band.ReadAsArray() == 0).astype(np.uint8))
    ds = None
    return str(reference), str(stable)


def main() -> None:
    if not XDEM.exists():
        sys.exit("xdem's venv is missing: run `make bench-xdem`, which installs it")
    rows = []
    with tempfile.TemporaryDirectory(prefix="coreg-peers-") as tmp:
        folder = pathlib.Path(tmp)
        for make in (analytic, simulated, srtm):
            case = make(folder)
            cell = abs(gdal.Open(case["dem"]).GetGeoTransform()[1])
            start = time.perf_counter()
            ours = coregister(case["dem"], Reference(case["reference"]), CoregParams(mask=case["mask"])).shift
            ours_s = time.perf_counter() - start
            reference, stable = for_xdem(case, folder)
            start = time.perf_counter()
            run = subprocess.run(
                [
                    str(XDEM),
                    str(REPO / "scripts" / "xdem_nuth_kaab.py"),
                    reference,
                    case["dem"],
                    *([stable] if stable else []),
                ],
                capture_output=True,
                text=True,
                check=True,
            )
            xdem_s = time.perf_counter() - start
            peer = json.loads(run.stdout.strip().splitlines()[-1])
            truth = case.get("shift", SHIFT)
            rows.append(
                {
                    "case": case["case"],
                    "truth E / N / U (m)": f"{truth[0]:+.2f} / {truth[1]:+.2f} / {-UP:+.2f}",
                    "Pushbroom": f"{ours.east:+.3f} / {ours.north:+.3f} / {ours.up:+.3f}",
                    f"xdem {peer['xdem']}": f"{peer['shift_x']:+.3f} / {peer['shift_y']:+.3f} / {peer['shift_z']:+.3f}",
                    "Pushbroom - xdem (cells)": f"{(ours.east - peer['shift_x']) / cell:+.4f} / "
                    f"{(ours.north - peer['shift_y']) / cell:+.4f}",
                    "Pushbroom - truth (cells)": f"{(ours.east - truth[0]) / cell:+.4f} / "
                    f"{(ours.north - truth[1]) / cell:+.4f}",
                    "time Pushbroom / xdem (s)": f"{ours_s:.1f} / {xdem_s:.1f}",
                }
            )
            print(rows[-1], file=sys.stderr, flush=True)
    print("# Co-registration: Pushbroom against xdem's NuthKaab\n")
    print(markdown_table(rows))


if __name__ == "__main__":
    main()
