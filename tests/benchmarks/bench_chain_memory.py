"""The surface chain through qgis_process, per scene size and execution: wall time and peak memory per step.

Scenes: simulated SPOT 5 HRG/HRS triplets of 10, 14.14 and 20 km (a quarter, a half and all of the
demo scene's area; supplied orientation = truth), matched at STEP 5. Steps, each one `qgis_process run`
with 2 workers of the execution: pushbroom:matchpoints, intersectpoints, interpolatedem (10 m) and
orthorectify (HRG on that DEM). Peak memory: the sum, over qgis_process and every process it starts (the
workers), of each one's VmHWM (its resident peak), sampled from /proc every SAMPLE_S; a sum of peaks,
so an upper bound of what the step held at once. The last rows give, per execution, the largest step
peak of each scene and its growth from the quarter to the whole scene."""
import pathlib
import shutil
import subprocess
import tempfile
import threading
import time

from osgeo import gdal

from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.helpers.processes import descendants
from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env

SIZES = (10.0, 14.14, 20.0)
EXECUTIONS = (("threads", 0), ("processes", 1))
WORKERS = 2
SAMPLE_S = 0.1


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


def chain(scene, folder, execution, env):
    """Rows of the steps of the chain on the simulated `scene` (simulate_scene's paths) in `folder`."""
    run = [QGIS_PROCESS, "run"]
    workers = [f"EXECUTION={execution}", f"WORKERS={WORKERS}"]
    block = folder / "block.gpkg"
    images = [f"IMAGES={scene['images'][n]['imagery']}" for n in ("HRG", "HRS1", "HRS2")]
    subprocess.run(run + ["pushbroom:createblock", "--", *images, f"DEM={scene['dsm']}", f"OUTPUT={block}"],
                   env=env, check=True, capture_output=True)
    steps = [("matchpoints", ["pushbroom:matchpoints", "--", f"BLOCK={block}", "STEP=5", *workers]),
             ("intersectpoints", ["pushbroom:intersectpoints", "--", f"BLOCK={block}", *workers,
                                  f"OUTPUT={folder / 'points.las'}"]),
             ("interpolatedem", ["pushbroom:interpolatedem", "--", f"INPUT={folder / 'points.las'}", "CELL=10",
                                 *workers, f"OUTPUT={folder / 'dem.tif'}"]),
             ("orthorectify", ["pushbroom:orthorectify", "--", f"BLOCK={block}", "IMAGE_NAME=HRG",
                               f"DEM={folder / 'dem.tif'}", *workers, f"OUTPUT={folder / 'ortho.tif'}"])]
    rows = []
    for name, args in steps:
        seconds, peak, processes, output = measured(run + args, env)
        count = [line.split()[-1] for line in output.splitlines() if line.startswith("COUNT:")]
        rows.append({"step": name, "points": count[0] if count else "", "seconds": seconds, "peak MB": peak,
                     "processes": processes})
    return rows


def run():
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        env = qgis_process_env(tmp / "profile")
        for size in SIZES:
            scene = simulate_scene(SceneConfig(size_km=size, error_scale=0.0, points=0), tmp / f"scene{size:g}")
            cols = gdal.Open(scene["images"]["HRG"]["imagery"]).RasterXSize
            for execution, index in EXECUTIONS:
                folder = tmp / f"run{size:g}-{execution}"
                folder.mkdir()
                for row in chain(scene, folder, index, env):
                    rows.append({"scene km": size, "HRG px": f"{cols} x {cols}", "execution": execution, **row})
                shutil.rmtree(folder)
            shutil.rmtree(tmp / f"scene{size:g}")
    for execution, _ in EXECUTIONS:
        peaks = [max(r["peak MB"] for r in rows if r["scene km"] == size and r["execution"] == execution)
                 for size in SIZES]
        rows.append({"scene km": "quarter -> whole", "execution": execution, "step": "largest step peak MB",
                     "peak MB": " / ".join(f"{p:.0f}" for p in peaks),
                     "seconds": f"growth {100.0 * (peaks[-1] / peaks[0] - 1.0):.1f} %"})
    return [{k: r.get(k, "") for k in ("scene km", "HRG px", "execution", "step", "points", "seconds", "peak MB",
                                        "processes")} for r in rows]


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table
    print(markdown_table(run()))
