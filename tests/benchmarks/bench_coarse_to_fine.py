"""Coarse-to-fine matching (match_coarse_to_fine) of the simulated SPOT 5 triplet HRG, HRS1, HRS2: seconds
per step (preprocessing, each pyramid level, MPGC; MultiPoints.stats) and in all, against region growing
(match_block, the demo's STEP 10, 2 workers; with its MPGC refinement of the group 3 points, the default,
and without) on the same images in the same run. Scene: the 10 km triplet
(bench_region_growing's scene(), the demo's SceneConfig at a quarter of its area; SIZE_KM to change it).
Supplied models, bench_region_growing's height range; after a warm-up of both matchers on the 3 km scene (JIT).
Then tiles: the 20 km demo scene whole (one 4000 px tile) and in tiles of TILES px, each run in its own
process: points, seconds and peak resident memory (memory bounded by the tile, not the scene)."""

import json
import subprocess
import sys
import tempfile
import time

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.coarse_to_fine import match_coarse_to_fine
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import match_block
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.benchmarks.bench_region_growing import HEIGHT_RANGE, scene

NAMES = ("HRG", "HRS1", "HRS2")
SIZE_KM = 10.0
WORKERS = 2
TILES = (4096, 2048, 1024)  # 4096: the 20 km scene's 4000 px images whole
CHILD = f"""
import json, sys, time
from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams, match_coarse_to_fine
folder, tile = sys.argv[1], int(sys.argv[2])
names = {NAMES!r}
models = [sensors.load(f"{{folder}}/{{n}}/METADATA.DIM") for n in names]
start = time.perf_counter()
points = match_coarse_to_fine([f"{{folder}}/{{n}}/IMAGERY.TIF" for n in names], models,
                              params=CoarseToFineParams(tile=tile),
                              height_range={HEIGHT_RANGE!r})
peak = [int(line.split()[1]) / 1024.0 for line in open("/proc/self/status") if line.startswith("VmHWM:")][0]
print(json.dumps({{"points": len(points), "three": points.stats["group3"], "seconds": time.perf_counter() - start,
                  "tiles": points.stats.get("tiles", 1), "peak_mib": peak}}))
"""


def both(images, models, height_range):
    """{matcher: (MultiPoints, seconds)} of the matchers on the same images."""

    def region_growing(refine):
        return lambda: match_block(
            images, models, names=NAMES, params=GrowParams(), height_range=height_range, workers=WORKERS, refine=refine
        )

    out = {}
    for label, match in (
        ("coarse-to-fine", lambda: match_coarse_to_fine(images, models, names=NAMES, height_range=height_range)),
        ("region growing + MPGC refinement", region_growing(True)),
        ("region growing", region_growing(False)),
    ):
        start = time.perf_counter()
        points = match()
        out[label] = points, time.perf_counter() - start
    return out


def inputs(folder):
    """Images and supplied models of a simulated triplet's folder."""
    return [Image(f"{folder}/{n}/IMAGERY.TIF") for n in NAMES], [
        sensors.load(f"{folder}/{n}/METADATA.DIM") for n in NAMES
    ]


def row(matcher, step, points, seconds, three="", peak=""):
    return {
        "matcher": matcher,
        "step": step,
        "points": points,
        "three-ray points": three,
        "seconds": seconds,
        "points/s": points / seconds if points else "",
        "peak MiB": peak,
    }


def run():
    with tempfile.TemporaryDirectory() as tmp:
        simulate_scene(SceneConfig.small(), tmp + "/scene")
        both(*inputs(tmp + "/scene"), HEIGHT_RANGE)
    folder = scene(SIZE_KM)
    images, models = inputs(folder)
    results = both(images, models, HEIGHT_RANGE)
    points, total = results["coarse-to-fine"]
    stats = points.stats
    label = f"coarse-to-fine ({stats['levels']} levels)"
    rows = []
    for step, seconds in stats["seconds"].items():
        n = stats["points_per_level"].get(step, len(points) if step == "mpgc" else 0)
        rows.append(row(label, step, n, seconds))
    rows.append(row(label, "total", len(points), total, stats["group3"]))
    for label in ("region growing + MPGC refinement", "region growing"):
        rg, seconds = results[label]
        three = int((rg.points["group"] >= 2).sum())
        rows.append(row(f"{label} ({WORKERS} workers)", "total", len(rg), seconds, three))
    big = scene(20.0)
    for tile in TILES:
        proc = subprocess.run([sys.executable, "-c", CHILD, str(big), str(tile)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(proc.stderr[-2000:])
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append(
            row(
                f"coarse-to-fine, 20 km scene, tile {tile} px ({r['tiles']} tiles)",
                "total",
                r["points"],
                r["seconds"],
                r["three"],
                r["peak_mib"],
            )
        )
    return rows


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    print(markdown_table(run()))
