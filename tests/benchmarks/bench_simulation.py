"""Scene simulator: time per stage of the default 20 x 20 km demo scenes (target: rendering under
60 s on 2 cores). Usage: bench_simulation.py [configuration ...]"""

import os
import sys
import tempfile
import time

from pushbroom.algorithms.simulation import SceneConfig, simulate_scene


class StageClock:
    """Feedback that records when each progress message arrives."""

    def __init__(self):
        self.marks = []

    def setProgress(self, percent):
        pass

    def isCanceled(self):
        return False

    def pushInfo(self, text):
        self.marks.append((time.perf_counter(), text))


def run(configurations=("spot5_triplet", "spot14_pair")):
    rows = []
    for configuration in configurations:
        config = SceneConfig(configuration=configuration)
        clock = StageClock()
        with tempfile.TemporaryDirectory() as tmp:
            start = time.perf_counter()
            simulate_scene(config, os.path.join(tmp, "scene"), clock)
            end = time.perf_counter()
        marks = clock.marks + [(end, "end")]
        render = 0.0
        for (t0, text), (t1, _) in zip(marks, marks[1:]):
            rows.append({"scene": f"{configuration} {config.size_km:g} km", "stage": text, "seconds": t1 - t0})
            render += (t1 - t0) if text.startswith("rendering") else 0.0
        rows.append(
            {"scene": f"{configuration} {config.size_km:g} km", "stage": "rendering, all images", "seconds": render}
        )
        rows.append({"scene": f"{configuration} {config.size_km:g} km", "stage": "total", "seconds": end - start})
    return rows


if __name__ == "__main__":
    for row in run(tuple(sys.argv[1:]) or ("spot5_triplet", "spot14_pair")):
        print(f"{row['scene']:24s} {row['stage']:60s} {row['seconds']:8.2f} s")
