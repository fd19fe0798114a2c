"""Region growing HRG -> HRS1 on simulated triplets: points/s per core with 1 and 2 threads, and
peak memory for the 20 km demo scene and a 10 km scene of a quarter of its area (each run in its
own process, so its peak resident memory is its own); on 2 threads also with one round of
automatic seeds (GrowParams.reseed_cell 0), the cost of the second."""

import json
import pathlib
import subprocess
import sys

from pushbroom.algorithms.matching.params import GrowParams

SCENES = pathlib.Path(__file__).resolve().parents[2] / "bench-output" / "scenes"

# the Jacksboro DEM spans 236-1076 m above the geoid (about -30 m to the ellipsoid), plus surface objects
HEIGHT_RANGE = (150.0, 1150.0)
CHILD = f"""
import json, sys, time, numba
from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing import match_pair
from pushbroom.algorithms.matching.pair_geometry import ImagePair
def peak_mib():
    # VmHWM: this process's own peak resident memory (ru_maxrss would carry the parent's across exec)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
folder, workers, reseed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
numba.set_num_threads(workers)
m1, m2 = sensors.load(folder + "/HRG/METADATA.DIM"), sensors.load(folder + "/HRS1/METADATA.DIM")
start = time.perf_counter()
records = match_pair(folder + "/HRG/IMAGERY.TIF", folder + "/HRS1/IMAGERY.TIF", m1, m2, GrowParams(reseed_cell=reseed),
                     height_range={HEIGHT_RANGE!r}, workers=workers)
print(json.dumps({{"points": int(len(records)), "seconds": time.perf_counter() - start,
                  "peak_mib": peak_mib()}}))
"""


def scene(size_km):
    """A simulated triplet of `size_km`, made once and kept under bench-output/scenes."""
    from pushbroom.algorithms.simulation import SceneConfig, simulate_scene

    folder = SCENES / f"triplet_{size_km:g}km"
    if not (folder / "truth" / "truth.json").exists():
        simulate_scene(SceneConfig(size_km=size_km), folder)
    return folder


def run_child(folder, workers, reseed=None):
    """Points, seconds and peak resident memory (MiB) of one region-growing run in a fresh process
    (reseed: GrowParams.reseed_cell, default its default)."""
    reseed = GrowParams().reseed_cell if reseed is None else reseed
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(folder), str(workers), str(reseed)], capture_output=True, text=True
    )
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run():
    rows = []
    for size in (10.0, 20.0):
        folder = scene(size)
        run_child(folder, 1)  # numba cache warm-up
        for workers, reseed in ((1, None), (2, None), (2, 0)):
            result = run_child(folder, workers, reseed)
            rounds = "one seed round" if reseed == 0 else "two seed rounds"
            rows.append(
                {
                    "scene": f"triplet {size:g} km, HRG -> HRS1, {rounds}",
                    "threads": workers,
                    "points": result["points"],
                    "seconds": result["seconds"],
                    "points/s": result["points"] / result["seconds"],
                    "points/s per core": result["points"] / result["seconds"] / workers,
                    "peak memory MiB": result["peak_mib"],
                }
            )
    return rows


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    print(markdown_table(run()))
