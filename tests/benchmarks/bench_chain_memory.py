"""The whole chain through qgis_process, per scene size and execution: time and peak memory per step, DEM accuracy.

Scenes: simulated SPOT 5 HRG/HRS triplets of 15, 30 and 60 km (a quarter, a half and all of a full SPOT
scene's width: HRG 3000^2, 6000^2 and 12 000^2 px), the demo's settings otherwise (seed 1, 30 points,
supplied orientation off by about 30 m), made once under bench-output/scenes. Steps, each one
`qgis_process run`, with the demo's parameters (scripts/demo.sh) and 2 workers of the execution for the
tiled ones: createblock (footprints on the true DSM), matchpoints (STEP 5, MPGC support), selecttiepoints,
importpoints (the first 19 control, the rest check), bundleadjust (automatic parameter selection),
intersectpoints, interpolatedem (10 m), orthorectify (HRG) and assessaccuracy (against the true DSM per
class). Peak memory: the sum, over qgis_process and every process it starts (the workers), of each
one's VmHWM (its resident peak), sampled from /proc every SAMPLE_S; a sum of peaks, so an upper bound of
what the step held at once. Per scene and execution a row gives the DEM's RMS / NMAD against the true
DSM per class; the last rows give, per execution, the largest step peak of each scene and its growth
from the quarter to the whole scene, over the surface chain's tiled steps (TILED) and over all steps
(createblock, bundleadjust and assessaccuracy read whole rasters: the reference DSM, the DEM).
On the largest scene (dem_agreement), the DEM of the intersected points is made again with the other
executions (cells defined, largest |dh|) and in one tile (median |dh|, 99th percentile of |dh| within 3
cells of the tile borders and away from them).

`dem_steps` (mode `dems`) runs coregisterdem and mergedems on the scene's true DSM and DTM (issue 40's memory).
`raster_steps` runs, without matching, the steps that read whole rasters of the scene: createblock
(footprints on the true DSM), importpoints, bundleadjust with the control points alone and the true DSM as
reference DTM, and orthorectify (HRG) on the true DSM (5 m, a larger raster than the chain's 10 m DEM).

`workers` runs the chain on one scene (15 km) with 1 and then 2 workers and gives the ratio per step;
`dense` runs it at STEP 1 with a 5 m DEM on one scene (20 km: HRG 4000 x 4000 px). `make bench` runs
every execution on the three scenes, then `workers` and `dense` with threads.

    python -m tests.benchmarks.bench_chain_memory [SIZE_KM ...] [threads|processes|dask ...] [raster|dems|workers|dense]
        [coregisterdem|mergedems|extractdtm ...]
"""

import contextlib
import csv
import pathlib
import shutil
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
from osgeo import gdal

from pushbroom.algorithms.task_runtime import BACKENDS
from tests.benchmarks.bench_region_growing import SCENES, scene
from tests.helpers.dem_cloud import read_raster
from tests.helpers.processes import descendants, peak_kb
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env

SIZES = (15.0, 30.0, 60.0)
WORKERS = 2
SAMPLE_S = 0.1
CONTROL = 19  # the first 19 points control, the rest check (as make demo)
TILED = ("matchpoints", "intersectpoints", "interpolatedem", "orthorectify")  # the surface chain's tiled steps
CLASSES = ("bare fields", "grass/crops", "forest", "city/buildings", "water")


def _importpoints(folder, block):
    """The importpoints step of the scene in `folder` into `block`: the first CONTROL points control, the rest check
    (as make demo)."""
    with open(folder / "points.csv", newline="") as f:
        check = ",".join(r["id"] for r in list(csv.DictReader(f))[CONTROL:])
    args = [f"BLOCK={block}", f"INPUT={folder / 'points.csv'}", f"CHECK_IDS={check}", "MEAS_SUFFIX=_meas"]
    return ("importpoints", ["pushbroom:importpoints", "--", *args])


@contextlib.contextmanager
def profile_env():
    """The qgis_process environment of a temporary profile with the plugin (qgis_process_env)."""
    with tempfile.TemporaryDirectory() as tmp:
        yield qgis_process_env(pathlib.Path(tmp) / "profile")


def measured(command, env):
    """Run `command`; returns (seconds, sum over the process tree of each process's VmHWM in MB, processes,
    its output)."""
    peaks = {}
    start = time.perf_counter()
    proc = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    done = threading.Event()

    def sample():
        while not done.is_set():
            for pid in [proc.pid] + descendants(proc.pid):
                peaks[pid] = max(peaks.get(pid, 0), peak_kb(pid))
            time.sleep(SAMPLE_S)

    sampler = threading.Thread(target=sample)
    sampler.start()
    output = proc.communicate()[0]
    done.set()
    sampler.join()
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({proc.returncode}):\n{output[-3000:]}")
    return seconds, sum(peaks.values()) / 1024.0, len(peaks), output


def chain(folder, out, execution, env, step=5, cell=10, workers=WORKERS):
    """Rows of the steps of the chain on the simulated scene in `folder`, matched every `step` px with a DEM
    of `cell` m and `workers` workers, writing into `out`; and the DEM's accuracy per class {class: (rms,
    nmad)}."""
    run = [QGIS_PROCESS, "run"]
    workers = [f"EXECUTION={BACKENDS.index(execution)}", f"WORKERS={workers}"]
    block, dsm = out / "block.gpkg", folder / "dsm.tif"
    images = [f"IMAGES={folder / n / 'IMAGERY.TIF'}" for n in ("HRG", "HRS1", "HRS2")]
    steps = [
        ("createblock", ["pushbroom:createblock", "--", *images, f"DEM={dsm}", f"OUTPUT={block}"]),
        (
            "matchpoints",
            ["pushbroom:matchpoints", "--", f"BLOCK={block}", f"STEP={step}", "MPGC_SUPPORT=true", *workers],
        ),
        ("selecttiepoints", ["pushbroom:selecttiepoints", "--", f"BLOCK={block}"]),
        _importpoints(folder, block),
        (
            "bundleadjust",
            [
                "pushbroom:bundleadjust",
                "--",
                f"BLOCK={block}",
                "FREE=auto",
                f"REFERENCE_DEM={dsm}",
                f"REPORT={out / 'adjustment.html'}",
            ],
        ),
        (
            "intersectpoints",
            ["pushbroom:intersectpoints", "--", f"BLOCK={block}", "POINTS=0", *workers, f"OUTPUT={out / 'points.las'}"],
        ),
        (
            "interpolatedem",
            [
                "pushbroom:interpolatedem",
                "--",
                f"INPUT={out / 'points.las'}",
                f"CELL={cell}",
                *workers,
                f"OUTPUT={out / 'dem.tif'}",
            ],
        ),
        (
            "orthorectify",
            [
                "pushbroom:orthorectify",
                "--",
                f"BLOCK={block}",
                "IMAGE_NAME=HRG",
                f"DEM={out / 'dem.tif'}",
                *workers,
                f"OUTPUT={out / 'ortho.tif'}",
            ],
        ),
        (
            "assessaccuracy",
            [
                "pushbroom:assessaccuracy",
                "--",
                f"REFERENCE={dsm}",
                f"POINTS={out / 'points.las'}",
                f"DEM={out / 'dem.tif'}",
                f"CLASS_RASTER={folder / 'classes.tif'}",
                f"REPORT={out / 'report.html'}",
                f"TABLE={out / 'accuracy.csv'}",
                f"DH={out / 'dh.tif'}",
            ],
        ),
    ]
    rows = []
    for name, args in steps:
        seconds, peak, processes, output = measured(run + args, env)
        print(f"  {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
        count = [line.split()[-1] for line in output.splitlines() if line.startswith("COUNT:")]
        rows.append(
            {
                "step": name,
                "points": count[0] if count else "",
                "seconds": seconds,
                "peak MB": peak,
                "processes": processes,
            }
        )
    with open(out / "accuracy.csv", newline="") as f:
        accuracy = {
            r["label"]: (float(r["rms"]), float(r["nmad"]))
            for r in csv.DictReader(f)
            if r["data"] == "DEM cells" and r["table"] == "per class"
        }
    return rows, accuracy


def dem_agreement(points, dem, execution, env, out, tile=1024):
    """Rows comparing the DEM `dem` (interpolatedem of `points` with `execution`, TILE `tile`) with the
    DEMs of the other executions and of a single tile."""
    reference = read_raster(dem)[0]
    rows = []
    runs = [(other, f"TILE={tile}") for other in BACKENDS if other != execution] + [(execution, "TILE=100000")]
    for other, tiling in runs:
        path = out / f"dem-{other}-{tiling.lower().replace('=', '')}.tif"
        seconds, peak, processes, _ = measured(
            [
                QGIS_PROCESS,
                "run",
                "pushbroom:interpolatedem",
                "--",
                f"INPUT={points}",
                "CELL=10",
                f"EXECUTION={BACKENDS.index(other)}",
                f"WORKERS={WORKERS}",
                tiling,
                f"OUTPUT={path}",
            ],
            env,
        )
        values = read_raster(path)[0]
        both = np.isfinite(values) & np.isfinite(reference)
        dh = np.abs(values - reference)[both]
        changed = float(np.mean(np.isfinite(values) != np.isfinite(reference)))
        if tiling == f"TILE={tile}":
            text = f"{other} vs {execution}: cells defined differ {100 * changed:.4f} %, largest |dh| {dh.max():.3g} m"
        else:
            index = np.indices(values.shape)
            near = (
                (np.minimum(index[0] % tile, tile - 1 - index[0] % tile) < 3)
                | (np.minimum(index[1] % tile, tile - 1 - index[1] % tile) < 3)
            )[both]
            text = (
                f"1 tile vs tiles of {tile}: cells defined differ {100 * changed:.4f} %, median |dh| "
                f"{np.median(dh):.3g} m, p99 |dh| along the tile borders {np.percentile(dh[near], 99):.3g} m, "
                f"away from them {np.percentile(dh[~near], 99):.3g} m"
            )
        rows.append(
            {
                "execution": other,
                "step": f"interpolatedem, {tiling}",
                "points": text,
                "seconds": seconds,
                "peak MB": peak,
                "processes": processes,
            }
        )
    return rows


def raster_steps(sizes=SIZES, execution="threads"):
    """Rows of the steps that read whole rasters (module docstring) per scene size."""

    def steps(folder, out, size):
        block, dsm = out / f"block-{size:g}.gpkg", folder / "dsm.tif"
        images = [f"IMAGES={folder / n / 'IMAGERY.TIF'}" for n in ("HRG", "HRS1", "HRS2")]
        return [
            ("createblock", ["pushbroom:createblock", "--", *images, f"DEM={dsm}", f"OUTPUT={block}"]),
            _importpoints(folder, block),
            (
                "bundleadjust, control points",
                ["pushbroom:bundleadjust", "--", f"BLOCK={block}", "USE_TIE_POINTS=false", f"REFERENCE_DEM={dsm}"],
            ),
            (
                "orthorectify on the true DSM",
                [
                    "pushbroom:orthorectify",
                    "--",
                    f"BLOCK={block}",
                    "IMAGE_NAME=HRG",
                    f"DEM={dsm}",
                    f"EXECUTION={BACKENDS.index(execution)}",
                    f"WORKERS={WORKERS}",
                    f"OUTPUT={out / f'ortho-{size:g}.tif'}",
                ],
            ),
        ]

    return _measured_steps(steps, sizes, execution)


def dem_steps(sizes=SIZES, execution="threads", only=()):
    """Rows of the DEM steps of issue 40 on the scene's true DSM and DTM (5 m), per scene size: coregisterdem (the
    DSM to the DTM, with a tilt), mergedems (the two, co-registered, with the precision rasters of a constant 0.5 m,
    the precision and count rasters written) and extractdtm (the DSM warped to UTM first: Bulldozer works in
    metres; DTM, DHM and mask)."""

    def steps(folder, out, size):
        dsm, dtm = folder / "dsm.tif", folder / "dtm.tif"
        sigma = out / f"sigma-{size:g}.tif"
        if not sigma.exists():
            ds = gdal.Open(str(dsm))
            gdal.Translate(str(sigma), ds, scaleParams=[[-1e6, 1e6, 0.5, 0.5]], outputType=gdal.GDT_Float32)
        tiles = [f"EXECUTION={BACKENDS.index(execution)}", f"WORKERS={WORKERS}"]
        utm = out / f"dsm-utm-{size:g}.tif"
        if not utm.exists():
            gdal.Warp(str(utm), str(dsm), dstSRS=_utm_of(dsm), xRes=5, yRes=5, resampleAlg="bilinear", errorThreshold=0)
        return [
            (
                "coregisterdem",
                [
                    "pushbroom:coregisterdem",
                    "--",
                    f"DEM={dsm}",
                    f"REFERENCE={dtm}",
                    "TILT=true",
                    *tiles,
                    f"OUTPUT={out / f'coreg-{size:g}.tif'}",
                ],
            ),
            (
                "mergedems",
                [
                    "pushbroom:mergedems",
                    "--",
                    f"DEMS={dsm}",
                    f"DEMS={dtm}",
                    f"PRECISIONS={sigma}",
                    f"PRECISIONS={sigma}",
                    *tiles,
                    f"OUTPUT={out / f'merged-{size:g}.tif'}",
                    f"PRECISION={out / f'merged-se-{size:g}.tif'}",
                    f"COUNT={out / f'merged-n-{size:g}.tif'}",
                ],
            ),
            (
                "extractdtm",
                [
                    "pushbroom:extractdtm",
                    "--",
                    f"DSM={utm}",
                    "TILE=2048",  # several tiles at 15 km too (3.7 k cells): each worker holds one at every size
                    *tiles,
                    f"OUTPUT={out / f'dtm-{size:g}.tif'}",
                    f"DHM={out / f'dhm-{size:g}.tif'}",
                    f"MASK={out / f'mask-{size:g}.tif'}",
                ],
            ),
        ]

    def chosen(folder, out, size):
        return [step for step in steps(folder, out, size) if not only or step[0] in only]

    return _measured_steps(chosen, sizes, execution)


def _utm_of(path):
    """'EPSG:326xx' of the UTM zone of the raster's centre (longitude/latitude)."""
    from pushbroom.algorithms.geodesy import utm_epsg

    ds = gdal.Open(str(path))
    gt = ds.GetGeoTransform()
    return f"EPSG:{utm_epsg(gt[0] + 0.5 * ds.RasterXSize * gt[1], gt[3] + 0.5 * ds.RasterYSize * gt[5])}"


def _measured_steps(steps, sizes, execution):
    """Each of `steps(scene folder, work folder, size)` [(name, qgis_process arguments)] run per scene size, its time
    and peak memory; then per step its peaks over the sizes and their growth from the first to the last."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        env, out = qgis_process_env(pathlib.Path(tmp) / "profile"), pathlib.Path(tmp)
        for size in sizes:
            for name, args in steps(scene(size), out, size):
                seconds, peak, processes, _ = measured([QGIS_PROCESS, "run"] + args, env)
                print(f"  {size:g} km {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
                rows.append(
                    {
                        "scene km": size,
                        "execution": execution,
                        "step": name,
                        "seconds": seconds,
                        "peak MB": peak,
                        "processes": processes,
                    }
                )
    for name in dict.fromkeys(r["step"] for r in rows):
        peaks = [r["peak MB"] for r in rows if r["step"] == name]
        rows.append(
            {
                "scene km": " -> ".join(f"{s:g}" for s in sizes),
                "execution": execution,
                "step": f"{name}: peak MB",
                "peak MB": " / ".join(f"{p:.0f}" for p in peaks),
                "seconds": f"growth {100.0 * (peaks[-1] / peaks[0] - 1.0):.1f} %",
            }
        )
    return [
        {k: r.get(k, "") for k in ("scene km", "execution", "step", "seconds", "peak MB", "processes")} for r in rows
    ]


def _chain_rows(size, execution, env, label="", agreement=False, **settings):
    """The rows of one chain (`chain` with `settings`) on the scene of `size` km, its execution labelled
    `label`; with `agreement`, also dem_agreement's rows on its points."""
    folder = scene(size)
    cols = gdal.Open(str(folder / "HRG" / "IMAGERY.TIF")).RasterXSize
    name = ", ".join(filter(None, (execution, label)))
    out = SCENES.parent / f"chain-{size:g}km-{name.replace(', ', '-').replace(' ', '')}"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    print(f"{size:g} km, {name}:", flush=True)
    steps, accuracy = chain(folder, out, execution, env, **settings)
    rows = [{"scene km": size, "HRG px": f"{cols} x {cols}", "execution": name, **row} for row in steps]
    rows.append(
        {
            "scene km": size,
            "execution": name,
            "step": "total",
            "seconds": sum(r["seconds"] for r in steps),
            "peak MB": max(r["peak MB"] for r in steps),
        }
    )
    rows.append(
        {
            "scene km": size,
            "execution": name,
            "step": "DEM - true DSM, RMS / NMAD (m)",
            "points": "; ".join(f"{c} {accuracy[c][0]:.2f} / {accuracy[c][1]:.2f}" for c in CLASSES if c in accuracy),
        }
    )
    if agreement:
        rows += [
            {"scene km": size, "check": True, **row}
            for row in dem_agreement(out / "points.las", out / "dem.tif", execution, env, out)
        ]
    shutil.rmtree(out)
    return rows


def workers_speed(size=15.0, execution="threads"):
    """The chain at STEP 5 on the scene of `size` km with 1 and with 2 workers: time per step and the
    speed-up."""
    with profile_env() as env:
        rows = {n: _chain_rows(size, execution, env, f"{n} worker{'s' * (n > 1)}", workers=n) for n in (1, 2)}
    speed = [
        {
            "scene km": size,
            "execution": execution,
            "step": f"{a['step']}: 1 / 2 workers",
            "seconds": f"x {a['seconds'] / b['seconds']:.2f}",
        }
        for a, b in zip(rows[1], rows[2])
        if isinstance(a.get("seconds"), float)
    ]
    return _columns(rows[1] + rows[2] + speed)


def dense_window(size=20.0, execution="threads"):
    """The chain matched at STEP 1 (a point per HRG pixel, 5 m DEM) on the scene of `size` km (20 km: HRG
    4000 x 4000 px, the issue's window of about 16 M nodes per image pair)."""
    with profile_env() as env:
        return _columns(_chain_rows(size, execution, env, "STEP 1", step=1, cell=5))


def _columns(rows):
    return [
        {
            k: r.get(k, "")
            for k in ("scene km", "HRG px", "execution", "step", "points", "seconds", "peak MB", "processes")
        }
        for r in rows
    ]


def run(sizes=SIZES, executions=BACKENDS):
    with profile_env() as env:
        rows = _run(sizes, executions, env)
    return rows + workers_speed() + dense_window()


def _run(sizes, executions, env):
    rows = []
    for size in sizes:
        for execution in executions:
            rows += _chain_rows(size, execution, env, agreement=size == max(sizes) and execution == executions[0])
    for execution in executions:
        for label, names in (("tiled steps", TILED), ("all steps", None)):
            peaks = [
                max(
                    r["peak MB"]
                    for r in rows
                    if r["scene km"] == size
                    and r["execution"] == execution
                    and isinstance(r.get("peak MB"), float)
                    and not r.get("check")
                    and (names is None or r["step"] in names)
                )
                for size in sizes
            ]
            rows.append(
                {
                    "scene km": " -> ".join(f"{s:g}" for s in sizes),
                    "execution": execution,
                    "step": f"largest peak MB, {label}",
                    "peak MB": " / ".join(f"{p:.0f}" for p in peaks),
                    "seconds": f"growth {100.0 * (peaks[-1] / peaks[0] - 1.0):.1f} %",
                }
            )
    return _columns(rows)


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    modes = {"raster", "dems", "workers", "dense"}
    dem_names = {"coregisterdem", "mergedems", "extractdtm"}  # dems: these steps only, where named
    sizes = tuple(float(a) for a in sys.argv[1:] if a not in BACKENDS and a not in modes and a not in dem_names)
    executions = tuple(a for a in sys.argv[1:] if a in BACKENDS) or BACKENDS
    mode = next((a for a in sys.argv[1:] if a in modes), None)
    if mode == "raster":
        print(markdown_table(raster_steps(sizes or SIZES, executions[0])))
    elif mode == "dems":
        print(markdown_table(dem_steps(sizes or SIZES, executions[0], tuple(a for a in sys.argv if a in dem_names))))
    elif mode == "workers":
        print(markdown_table(workers_speed(*sizes[:1], *executions[:1])))
    elif mode == "dense":
        print(markdown_table(dense_window(*sizes[:1], *executions[:1])))
    else:
        with profile_env() as env:
            print(markdown_table(_run(sizes or SIZES, executions, env)))
