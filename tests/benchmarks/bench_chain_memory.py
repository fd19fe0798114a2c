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
from the quarter to the whole scene.

    python -m tests.benchmarks.bench_chain_memory [SIZE_KM ...] [threads|processes|dask ...]
"""
import csv
import shutil
import subprocess
import sys
import threading
import time

from osgeo import gdal

from pushbroom.algorithms.execution import BACKENDS
from tests.benchmarks.bench_region_growing import SCENES, scene
from tests.helpers.processes import descendants
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env

SIZES = (15.0, 30.0, 60.0)
EXECUTIONS = ("threads", "processes")
WORKERS = 2
SAMPLE_S = 0.1
CONTROL = 19          # the first 19 points control, the rest check (as make demo)
CLASSES = ("bare fields", "grass/crops", "forest", "city/buildings", "water")


def _hwm_kb(pid):
    try:
        with open(f"/proc/{pid}/status", encoding="utf-8") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


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
                peaks[pid] = max(peaks.get(pid, 0), _hwm_kb(pid))
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


def chain(folder, out, execution, env):
    """Rows of the steps of the chain on the simulated scene in `folder`, writing into `out`; and the DEM's
    accuracy per class {class: (rms, nmad)}."""
    run = [QGIS_PROCESS, "run"]
    workers = [f"EXECUTION={BACKENDS.index(execution)}", f"WORKERS={WORKERS}"]
    block, dsm = out / "block.gpkg", folder / "dsm.tif"
    with open(folder / "points.csv", newline="") as f:
        check = ",".join(r["id"] for r in list(csv.DictReader(f))[CONTROL:])
    images = [f"IMAGES={folder / n / 'IMAGERY.TIF'}" for n in ("HRG", "HRS1", "HRS2")]
    steps = [("createblock", ["pushbroom:createblock", "--", *images, f"DEM={dsm}", f"OUTPUT={block}"]),
             ("matchpoints", ["pushbroom:matchpoints", "--", f"BLOCK={block}", "STEP=5", "MPGC_SUPPORT=true",
                              *workers]),
             ("selecttiepoints", ["pushbroom:selecttiepoints", "--", f"BLOCK={block}"]),
             ("importpoints", ["pushbroom:importpoints", "--", f"BLOCK={block}", f"INPUT={folder / 'points.csv'}",
                               f"CHECK_IDS={check}", "MEAS_SUFFIX=_meas"]),
             ("bundleadjust", ["pushbroom:bundleadjust", "--", f"BLOCK={block}", "FREE=auto", f"REFERENCE_DEM={dsm}",
                               f"REPORT={out / 'adjustment.html'}"]),
             ("intersectpoints", ["pushbroom:intersectpoints", "--", f"BLOCK={block}", "POINTS=0", *workers,
                                  f"OUTPUT={out / 'points.las'}"]),
             ("interpolatedem", ["pushbroom:interpolatedem", "--", f"INPUT={out / 'points.las'}", "CELL=10",
                                 *workers, f"OUTPUT={out / 'dem.tif'}"]),
             ("orthorectify", ["pushbroom:orthorectify", "--", f"BLOCK={block}", "IMAGE_NAME=HRG",
                               f"DEM={out / 'dem.tif'}", *workers, f"OUTPUT={out / 'ortho.tif'}"]),
             ("assessaccuracy", ["pushbroom:assessaccuracy", "--", f"REFERENCE={dsm}", f"POINTS={out / 'points.las'}",
                                 f"DEM={out / 'dem.tif'}", f"CLASS_RASTER={folder / 'classes.tif'}",
                                 f"REPORT={out / 'report.html'}", f"TABLE={out / 'accuracy.csv'}",
                                 f"DH={out / 'dh.tif'}"])]
    rows = []
    for name, args in steps:
        seconds, peak, processes, output = measured(run + args, env)
        print(f"  {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
        count = [line.split()[-1] for line in output.splitlines() if line.startswith("COUNT:")]
        rows.append({"step": name, "points": count[0] if count else "", "seconds": seconds, "peak MB": peak,
                     "processes": processes})
    with open(out / "accuracy.csv", newline="") as f:
        accuracy = {r["label"]: (float(r["rms"]), float(r["nmad"])) for r in csv.DictReader(f)
                    if r["data"] == "DEM cells" and r["table"] == "per class"}
    return rows, accuracy


def run(sizes=SIZES, executions=EXECUTIONS):
    rows = []
    env = qgis_process_env(SCENES.parent / "chain-profile")
    for size in sizes:
        folder = scene(size)
        cols = gdal.Open(str(folder / "HRG" / "IMAGERY.TIF")).RasterXSize
        for execution in executions:
            print(f"{size:g} km, {execution}:", flush=True)
            out = SCENES.parent / f"chain-{size:g}km-{execution}"
            shutil.rmtree(out, ignore_errors=True)
            out.mkdir(parents=True)
            steps, accuracy = chain(folder, out, execution, env)
            for row in steps:
                rows.append({"scene km": size, "HRG px": f"{cols} x {cols}", "execution": execution, **row})
            rows.append({"scene km": size, "execution": execution, "step": "total",
                         "seconds": sum(r["seconds"] for r in steps)})
            rows.append({"scene km": size, "execution": execution, "step": "DEM - true DSM, RMS / NMAD (m)",
                         "points": "; ".join(f"{c} {accuracy[c][0]:.2f} / {accuracy[c][1]:.2f}" for c in CLASSES
                                             if c in accuracy)})
            shutil.rmtree(out)
    for execution in executions:
        peaks = [max(r["peak MB"] for r in rows if r["scene km"] == size and r["execution"] == execution
                     and "peak MB" in r) for size in sizes]
        rows.append({"scene km": " -> ".join(f"{s:g}" for s in sizes), "execution": execution,
                     "step": "largest step peak MB", "peak MB": " / ".join(f"{p:.0f}" for p in peaks),
                     "seconds": f"growth {100.0 * (peaks[-1] / peaks[0] - 1.0):.1f} %"})
    return [{k: r.get(k, "") for k in ("scene km", "HRG px", "execution", "step", "points", "seconds", "peak MB",
                                        "processes")} for r in rows]


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table
    sizes = tuple(float(a) for a in sys.argv[1:] if a not in BACKENDS) or SIZES
    executions = tuple(a for a in sys.argv[1:] if a in BACKENDS) or EXECUTIONS
    print(markdown_table(run(sizes, executions)))
