"""`make bench-peers`: Pushbroom against CNES CARS 1.3.0, one after the other in the same run (not in CI), on
the real Pleiades triplet and on two simulated 3 km SPOT 5 triplets: SceneConfig.small() and a check scene (seed 2, 4
km west: small fields among forest; the default dense chain, region growing and CARS only).

Pushbroom, each step one `qgis_process run` with 2 threads: createblock (no DEM, no height: the range is found
by matching), matchpoints (STRATEGY 2, dense, every pixel of the first image; again with DENSE_MPGC, the MPGC
refinement of the three-ray points; region growing, STRATEGY 0, beside them on the simulated scene),
intersectpoints, interpolatedem. The dense DEM is the dense pipeline model's
(resources/models/pushbroom_pipeline_dense.model3): per-cell medians of the LSM-refined points, an empty cell the
points of the cells around it (RADIUS 1), the gaps within 10 cells filled and flagged in the mask raster. A
second, untimed interpolatedem of the same cloud takes every point instead (FALLBACK: a cell without refined
points takes the semi-global ones) and fills nothing. Region growing's DEM is the TIN.

CARS 1.3.0 from its own venv (build/peers/cars, numpy 2; `make bench-peers` installs it), its default pipeline,
heights on the ellipsoid as Pushbroom's (output geoid off). Pleiades: the three images with the RPCs of their
GeoTIFFs, pairs img_02-img_01 and img_02-img_03, 0.5 m. Simulated scene: HRG, HRS1 and HRS2 with the RPCs
pushbroom:fitrpc fits to the truth orientation (IMAGERY_RPC.TXT beside each image, as GDAL reads them), pairs
HRG-HRS1 and HRG-HRS2, 10 m; Pushbroom's chain is given the same truth orientation, so both tools' errors are
their matching's.

Printed: each tool's time and peak memory (the sum of the processes' VmHWM) and the ratio of the times.
Pleiades: each DSM's coverage of the cells whose centre lies in all three images (at the median height;
Pushbroom's split by its mask: own points, the cells around, filled) and Pushbroom's DSM minus CARS's (GDAL
warps CARS's onto Pushbroom's grid), likewise split. Simulated scene: each 10 m DSM against the true DSM and the
true DTM by class at the evaluation cells of tests/helpers/dsm_comparison.py (RMS over the cells each DSM
covers, its coverage, and the RMS over the cells all of them cover), and the coverage of the non-water cells; and
issue 40's DTM: pushbroom:extractdtm (CNES Bulldozer) on Pushbroom's dense DSM and on CARS's, each against the true
DTM by class, beside the DSM's own departure from it.

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
from pushbroom.algorithms.crs import transform
from pushbroom.algorithms.quality.rasters import open_raster, read_grid, warp_to
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface.tin_grid import Grid
from tests.benchmarks.bench_chain_memory import measured
from tests.benchmarks.benchutil import SHARED_DATA
from tests.benchmarks.run_all import markdown_table
from tests.helpers.dsm_comparison import CELL, NAMES, Truth
from tests.helpers.qgis_process_profile import QGIS_PROCESS, REPO, qgis_process_env
from tests.helpers.real_dsm import footprint_mask

DATA = SHARED_DATA / "pleiades_triplet"
IMAGES = [DATA / f"img_0{k}.tif" for k in (2, 1, 3)]  # the reference first, as both tools pair them
CARS = REPO / "build" / "peers" / "cars" / "bin" / "cars"
WORKERS = 2
#: the second simulated scene (studies/dense_precision.py's check scene: small fields among forest)
CHECK_SCENE = SceneConfig.small(seed=2, centre_lon=-84.235)


def qgis_steps(steps, env, label):
    """Rows of `steps` [(name, qgis_process arguments)], each one `qgis_process run`, timed."""
    rows = []
    for name, args in steps:
        seconds, peak, _, _ = measured([QGIS_PROCESS, "run"] + args, env)
        print(f"  {label} {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
        rows.append({"tool": label, "step": name, "seconds": seconds, "peak MB": peak})
    return rows


#: interpolatedem's settings: the dense pipeline model's, every dense point, region growing's TIN
DENSE_MODEL = ["METHOD=1", "FALLBACK=false", "FILL=10"]
EVERY_POINT = ["METHOD=1"]
TIN = ["METHOD=0"]
#: matchpoints' dense strategy with the MPGC refinement of a triplet's three-ray points
MPGC = ["DENSE_MPGC=true"]


def chain(out, images, strategy, cell, surface, orientation=(), label="Pushbroom", match=()):
    """(rows, DEM, mask or None, block) of Pushbroom's chain: createblock with no DEM and no height
    (`orientation` files, or those beside the images), matchpoints with `strategy` (2 dense, 0 region growing)
    and the further arguments `match`, intersectpoints, and interpolatedem with the `surface` settings
    (surface_step)."""
    block, cloud = out / "block.gpkg", out / "points.las"
    tiled = ["EXECUTION=0", f"WORKERS={WORKERS}"]
    kind = "dense" if strategy == 2 else "region growing"
    steps = [
        (
            "createblock",
            [
                "pushbroom:createblock",
                "--",
                *(f"IMAGES={p}" for p in images),
                *(f"ORIENTATION={p}" for p in orientation),
                *tiled,
                f"OUTPUT={block}",
            ],
        ),
        (
            f"matchpoints ({kind}{''.join(' ' + a for a in match)})",
            ["pushbroom:matchpoints", "--", f"BLOCK={block}", f"STRATEGY={strategy}", *match, *tiled],
        ),
        (
            "intersectpoints",
            ["pushbroom:intersectpoints", "--", f"BLOCK={block}", "POINTS=0", *tiled, f"OUTPUT={cloud}"],
        ),
    ]
    out.mkdir(parents=True, exist_ok=True)
    rows = qgis_steps(steps, qgis_process_env(out / "profile"), label)
    more, dem, mask = surface_step(out, cloud, cell, surface, label)
    return rows + more, dem, mask, block


def surface_step(out, cloud, cell, surface, label):
    """(rows, DEM, mask or None) of interpolatedem of `cloud` at `cell` with the `surface` settings."""
    name = "-".join(a.replace("=", "").lower() for a in surface)
    dem, mask = out / f"dem-{name}.tif", out / f"mask-{name}.tif"
    cells = "METHOD=1" in surface
    rows = qgis_steps(
        [
            (
                f"interpolatedem ({' '.join(surface)}, {cell:g} m)",
                [
                    "pushbroom:interpolatedem",
                    "--",
                    f"INPUT={cloud}",
                    f"CELL={cell}",
                    *surface,
                    "EXECUTION=0",
                    f"WORKERS={WORKERS}",
                    f"OUTPUT={dem}",
                    *([f"MASK={mask}"] if cells else []),
                ],
            )
        ],
        qgis_process_env(out / f"profile-{name}"),
        label,
    )
    return rows, dem, mask if cells else None


def cars(out, images, pairs, resolution, label="CARS 1.3.0"):
    """(rows, DSM path) of CARS on `images` {name: path} (RPCs in their GeoTIFFs or _RPC.TXT files)."""
    conf = out / "cars.json"
    out.mkdir(parents=True, exist_ok=True)
    conf.write_text(
        json.dumps(
            {
                "input": {
                    "sensors": {n: {"image": str(p)} for n, p in images.items()},
                    "pairing": [list(p) for p in pairs],
                },
                "output": {"directory": str(out / "cars"), "resolution": resolution, "geoid": False},
            }
        )
    )
    seconds, peak, _, output = measured([str(CARS), "--logtype", "plain", str(conf)], dict(os.environ))
    dsm = out / "cars" / "dsm" / "dsm.tif"
    if not dsm.exists():
        sys.exit(f"CARS made no DSM:\n{output[-3000:]}")
    print(f"  {label}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
    return [{"tool": label, "step": "whole pipeline", "seconds": seconds, "peak MB": peak}], dsm


def compare(dem, mask, dsm, label, cars_row=True):
    """Rows: the coverage of the Pleiades footprint of Pushbroom's DSM `dem` (with its `mask`; `label` names
    its settings) and of CARS's `dsm` on Pushbroom's grid, and their difference."""
    source = gdal.Open(str(mask)).ReadAsArray()
    grid = read_grid(open_raster(dem, "Pushbroom's DSM"))
    ours, (rows, cols), gt = grid.values, grid.shape, grid.geotransform
    theirs = warp_to(open_raster(dsm, "CARS's DSM"), grid, "bilinear")
    models = [sensors.load(p) for p in IMAGES]
    inside = footprint_mask(Grid(gt[0], gt[3], gt[1], cols, rows), grid.srs, models, float(np.nanmedian(ours)))
    both = inside & np.isfinite(ours) & np.isfinite(theirs)
    share = {k: 100 * (source == v)[inside].mean() for k, v in (("own", 0), ("around", 2), ("filled", 1))}
    rows = [
        {
            "tool": f"Pushbroom, {label}",
            "step": "coverage of the common footprint",
            "value": f"{100 * np.isfinite(ours[inside]).mean():.1f} % (own points {share['own']:.1f} %, the cells "
            f"around {share['around']:.1f} %, filled {share['filled']:.1f} %)",
        }
    ]
    if cars_row:
        rows.append(
            {
                "tool": "CARS 1.3.0",
                "step": "coverage of the common footprint",
                "value": f"{100 * np.isfinite(theirs[inside]).mean():.1f} %",
            }
        )
    for what, cells in (
        ("all", both),
        ("own points", both & (source == 0)),
        ("the cells around", both & (source == 2)),
        ("filled", both & (source == 1)),
    ):
        if cells.any():
            diff = summarize((ours - theirs)[cells])
            rows.append(
                {
                    "tool": f"Pushbroom, {label} - CARS",
                    "step": f"DSM differences, {what}",
                    "value": f"N {diff.n}, median {diff.median:+.3f} m, NMAD {diff.nmad:.3f} m, RMS {diff.rms:.3f} m",
                }
            )
    return rows


def pleiades(tmp):
    """Rows of the Pleiades triplet: both tools' times, their ratio, coverage and difference."""
    out = tmp / "pushbroom"
    ours, dem, mask, _ = chain(out, IMAGES, 2, 0.5, DENSE_MODEL)
    _, every, every_mask = surface_step(out, out / "points.las", 0.5, EVERY_POINT, "Pushbroom (untimed)")
    names = ("one", "two", "three")
    theirs, dsm = cars(tmp / "cars", dict(zip(names, IMAGES)), [("one", "two"), ("one", "three")], 0.5)
    total = sum(r["seconds"] for r in ours)
    rows = ours + [{"tool": "Pushbroom", "step": "total", "seconds": total}] + theirs
    rows.append({"tool": "CARS / Pushbroom", "step": "time ratio", "value": f"{theirs[0]['seconds'] / total:.2f}"})
    mpgc, mpgc_dem, mpgc_mask, _ = chain(tmp / "mpgc", IMAGES, 2, 0.5, DENSE_MODEL, label="Pushbroom MPGC", match=MPGC)
    mpgc_total = sum(r["seconds"] for r in mpgc)
    rows += mpgc + [
        {"tool": "Pushbroom MPGC", "step": "total", "seconds": mpgc_total},
        {"tool": "CARS / Pushbroom MPGC", "step": "time ratio", "value": f"{theirs[0]['seconds'] / mpgc_total:.2f}"},
    ]
    return (
        rows
        + compare(dem, mask, dsm, "refined, filled")
        + compare(every, every_mask, dsm, "every point", False)
        + compare(mpgc_dem, mpgc_mask, dsm, "MPGC, refined, filled", False)
    )


def sample(path, truth):
    """The raster `path` at the evaluation cells of `truth` (dsm_comparison.Truth): the value of the cell holding
    each centre, NaN outside or on nodata (not quality.height_differences.reference_at_points' bilinear, which
    leaves the cells next to a gap undefined: the coverage counted would not be the DSM's)."""
    grid = read_grid(open_raster(path, "a DSM"))
    gt, values = grid.geotransform, grid.values
    xy = transform(truth.srs, grid.srs, np.column_stack([truth.x, truth.y]), "the evaluation cells")
    j, i = np.floor((xy[:, 0] - gt[0]) / gt[1]).astype(int), np.floor((xy[:, 1] - gt[3]) / gt[5]).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < values.shape[0]) & (j < values.shape[1])
    out = np.full(len(truth.x), np.nan)
    out[inside] = values[i[inside], j[inside]]
    return out


def simulated(tmp, config=None, scene="", full=True):
    """Rows of a simulated 3 km SPOT 5 triplet (module docstring; `config` default SceneConfig.small()), labelled
    with `scene`; without `full`, only the default dense chain, region growing and CARS."""
    paths = simulate_scene(config or SceneConfig.small(), str(tmp / "scene"))
    images = [paths["images"][n]["imagery"] for n in NAMES]
    orientation = [paths["truth_metadata"][n] for n in NAMES]
    rows, dems = [], {}
    chains = (("dense", 2, DENSE_MODEL, ()), ("dense MPGC", 2, DENSE_MODEL, MPGC), ("region growing", 0, TIN, ()))
    for label, strategy, surface, match in chains if full else chains[::2]:
        steps, dems[label], _, block = chain(
            tmp / label.replace(" ", "-"), images, strategy, CELL, surface, orientation, f"Pushbroom {label}", match
        )
        rows += steps + [{"tool": f"Pushbroom {label}", "step": "total", "seconds": sum(r["seconds"] for r in steps)}]
    if full:
        _, dems["dense, every point"], _ = surface_step(
            tmp / "dense", tmp / "dense" / "points.las", CELL, EVERY_POINT, "Pushbroom dense (untimed)"
        )
    rows += qgis_steps(
        [("fitrpc", ["pushbroom:fitrpc", "--", f"BLOCK={block}", "OVERWRITE=true"])],
        qgis_process_env(tmp / "rpc-profile"),
        "Pushbroom (for CARS)",
    )
    steps, dems["CARS"] = cars(tmp / "cars", dict(zip(NAMES, images)), [("HRG", "HRS1"), ("HRG", "HRS2")], CELL)
    rows += steps
    truth = Truth(paths)
    for reference, heights in (("DSM", truth.h), ("DTM", truth.dtm_h)):
        dh = {label: sample(path, truth) - heights for label, path in dems.items()}
        common = np.all([np.isfinite(d) for d in dh.values()], axis=0)
        tables = {label: truth.table(d, common) for label, d in dh.items()}
        for zone in tables["dense"]:
            rows.append(
                {
                    "tool": f"10 m DSM - true {reference}: RMS (coverage; RMS on the cells all cover)",
                    "step": zone,
                    "value": ", ".join(
                        f"{label} {t[zone][2]:.2f} m ({100 * t[zone][1]:.0f} %; {t[zone][5]:.2f})"
                        for label, t in tables.items()
                    ),
                }
            )
    if full:  # dh: the DSMs minus the true DTM, the last of the loop above
        dsms = {"Pushbroom dense": dems["dense"], "CARS 1.3.0": dems["CARS"]}
        rows += dtm_rows(tmp, dsms, truth, {"Pushbroom dense": dh["dense"], "CARS 1.3.0": dh["CARS"]})
    for label, d in dh.items():
        rows.append(
            {
                "tool": label,
                "step": "coverage of the non-water cells",
                "value": f"{100 * np.isfinite(d[~truth.water]).mean():.1f} %",
            }
        )
    return [dict(r, tool=scene + r["tool"]) for r in rows]


def dtm_rows(tmp, dsms, truth, dsm_dh):
    """Issue 40's DTM table: pushbroom:extractdtm (CNES Bulldozer, its defaults) on each 10 m DSM of `dsms` {label:
    path} (CARS's warped onto the CRS of Pushbroom's, a UTM zone, first: Bulldozer takes metres), the DTM minus the
    true DTM by class (RMS), beside the DSM's own departure from the true DTM, `dsm_dh` {label: at the evaluation
    cells}."""
    rows, dtms = [], {}
    env = qgis_process_env(tmp / "dtm-profile")
    projection = open_raster(dsms["Pushbroom dense"], "the dense DEM").GetProjection()
    for label, path in dsms.items():
        name = label.split()[0].lower()
        metric = tmp / f"dsm-{name}-utm.tif"
        if label == "Pushbroom dense":
            metric = path  # in its UTM zone at CELL already
        else:
            gdal.Warp(str(metric), str(path), dstSRS=projection, xRes=CELL, yRes=CELL, errorThreshold=0)
        dtms[label] = tmp / f"dtm-{name}.tif"
        rows += qgis_steps(
            [
                (
                    f"extractdtm ({label})",
                    [
                        "pushbroom:extractdtm",
                        "--",
                        f"DSM={metric}",
                        "EXECUTION=1",
                        f"WORKERS={WORKERS}",
                        f"OUTPUT={dtms[label]}",
                    ],
                )
            ],
            env,
            "Pushbroom",
        )
    dtm_dh = {label: sample(str(path), truth) - truth.dtm_h for label, path in dtms.items()}
    common = np.all([np.isfinite(d) for d in (*dsm_dh.values(), *dtm_dh.values())], axis=0)
    dsm_tables = {label: truth.table(d, common) for label, d in dsm_dh.items()}
    dtm_tables = {label: truth.table(d, common) for label, d in dtm_dh.items()}
    for zone in dtm_tables["Pushbroom dense"]:
        rows.append(
            {
                "tool": "Bulldozer's DTM - true DTM, RMS on the cells all cover (the DSM's own - true DTM)",
                "step": zone,
                "value": ", ".join(
                    f"{label} {dtm_tables[label][zone][5]:.2f} m ({dsm_tables[label][zone][5]:.2f})" for label in dsms
                ),
            }
        )
    return rows


def run():
    if not DATA.is_dir():
        sys.exit(f"{DATA} is absent")
    if not CARS.exists():
        sys.exit(f"{CARS} is missing: run make bench-peers, which installs CARS 1.3.0 into build/peers/cars")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        rows = (
            pleiades(tmp / "pleiades")
            + simulated(tmp / "simulated")
            + simulated(tmp / "check", CHECK_SCENE, "check scene: ", full=False)
        )
    return [{k: r.get(k, "") for k in ("tool", "step", "seconds", "peak MB", "value")} for r in rows]


if __name__ == "__main__":
    print(markdown_table(run()))
