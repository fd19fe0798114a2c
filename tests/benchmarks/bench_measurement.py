"""Interactive measurement: block edits with 500 points, and the transfer of one click.

Single edits of a block holding 500 control/check points with 1500 image measurements
(MeasurementStore; each edit one committed SQLite transaction), loading them, and the least-squares
transfer of one click into the other two images of the simulated SPOT 5 triplet with markers (per
click; median over its points after a warm-up click)."""

import csv
import pathlib
import tempfile
import time

import numpy as np

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.measurement.transfer import Click, transfer
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene

POINTS = 500
REPEAT = 50


def _median_ms(function, repeat=REPEAT):
    times = []
    for k in range(repeat):
        start = time.perf_counter()
        function(k)
        times.append(time.perf_counter() - start)
    return 1000.0 * float(np.median(times)), 1000.0 * float(np.max(times))


def _store_rows(store):
    edits = {
        "put_point (edit an existing point)": lambda k: store.put_point(
            "B250", "control", -84.19, 36.61, 300.0 + k, 2.5, 2.5, 2.2
        ),
        "put_point (new point)": lambda k: store.put_point(f"N{k}", "check", -84.19, 36.61, 300.0, 2.5, 2.5, 2.2),
        "put_measurement (move)": lambda k: store.put_measurement("B250", 2, 120.0 + 0.01 * k, 200.0),
        "put_measurement (new)": lambda k: store.put_measurement(f"N{k}", 1, 100.0, 200.0),
        "rename_point": lambda k: store.rename_point(f"N{k}", f"M{k}"),
        "delete_measurement": lambda k: store.delete_measurement(f"M{k}", 1),
        "delete_point": lambda k: store.delete_point(f"M{k}"),
    }
    rows = []
    for name, edit in edits.items():
        median, worst = _median_ms(edit)
        rows.append({"step": name, "points": POINTS, "median ms": median, "max ms": worst})
    start = time.perf_counter()
    obs = store.load()
    rows.append(
        {
            "step": f"load() ({len(obs.measurements)} measurements)",
            "points": len(obs.points),
            "median ms": 1000.0 * (time.perf_counter() - start),
            "max ms": float("nan"),
        }
    )
    return rows


def run():
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        paths = simulate_scene(SceneConfig.small(markers=True), pathlib.Path(folder) / "scene")
        names = ("HRG", "HRS1", "HRS2")
        images = {n: paths["images"][n]["imagery"] for n in names}
        opened = Block.open_images([images[n] for n in names])
        path = pathlib.Path(folder) / "block.gpkg"
        Block.create(path, opened, height=300.0)
        store = Block(path).measurement_store()
        for k in range(POINTS):
            store.put_point(f"B{k}", "control", -84.19 + 1e-5 * k, 36.61, 300.0, 2.5, 2.5, 2.2)
            for image_id in (1, 2, 3):
                store.put_measurement(f"B{k}", image_id, 100.0 + 0.1 * k, 200.0)
        rows += _store_rows(store)
        models = {name: model for name, _, _, model in opened}
        with open(paths["points"], newline="") as f:
            points = list(csv.DictReader(f))
        for source, how in (("HRG", "point height"), ("HRS1", "point height"), ("HRG", "height range +-500 m")):

            def click(k):
                r = points[k % len(points)]
                h = float(r["h"]) if how == "point height" else (float(r["h"]) - 500.0, float(r["h"]) + 500.0)
                return transfer(
                    images, models, Click(source, float(r[f"{source}_col"]), float(r[f"{source}_row"])), height=h
                )

            click(0)
            median, worst = _median_ms(click, len(points))
            rows.append(
                {
                    "step": f"transfer {source} -> other two images ({how})",
                    "points": len(points),
                    "median ms": median,
                    "max ms": worst,
                }
            )
    return rows


if __name__ == "__main__":
    for r in run():
        print(f"{r['step']}: median {r['median ms']:.1f} ms, max {r['max ms']:.1f} ms")
