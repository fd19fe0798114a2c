"""Multi-image point storage: save/load of 2 million points (6 million observations) as the
block's .npz point store, the combination of three matching runs, tie point selection, and writing
the display point layer into the GeoPackage."""

import pathlib
import tempfile
import time

import numpy as np

from pushbroom.algorithms.block import Block, points as points_store
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.matching.records import PAIR_DTYPE
from pushbroom.algorithms.matching.three_combinations import Transfer, combine
from pushbroom.algorithms.matching.tiepoints import select_tie_points
from tests.benchmarks.benchutil import best_time
from tests.helpers.points_synthetic import FlatModel, synthetic

N = 2_000_000


def _block(folder):
    path = pathlib.Path(folder) / "bench.gpkg"
    create_schema(path)
    return path


def _pairs(n, rng):
    r = np.zeros(n, PAIR_DTYPE)
    r["x1"], r["y1"] = rng.uniform(0, 12000, n), rng.uniform(0, 12000, n)
    r["x2"], r["y2"] = r["x1"] + rng.normal(0, 0.05, n), r["y1"] + rng.normal(0, 0.05, n)
    r["rho"] = rng.uniform(0.6, 1, n)
    return r


def run():
    mp = synthetic(N)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        block = _block(folder)
        folders = []  # each store writes a new, versioned point folder
        save = best_time(lambda: folders.append(Block(block).store_points(mp)), repeat=2)
        load = best_time(lambda: Block(block).points(), repeat=2)
        size = pathlib.Path(folders[-1]).stat().st_size / 1e6
        rows.append(
            {"step": f"save {N} points, {len(mp.observations)} observations (.npz, {size:.0f} MB)", "seconds": save}
        )
        rows.append({"step": "load them", "seconds": load})
        rng = np.random.default_rng(0)
        a = _pairs(N, rng)
        b = _pairs(N, rng)
        c = _pairs(N, rng)
        src = np.arange(N)
        rows.append(
            {
                "step": f"combine (a), (b), (c) of {N} points each",
                "seconds": best_time(lambda: combine(a, Transfer(b, src), Transfer(c, src)), repeat=1),
            }
        )
        rows.append(
            {
                "step": "select tie points (100 px cells)",
                "seconds": best_time(lambda: select_tie_points(mp, 100.0), repeat=1),
            }
        )
        small = mp.subset(np.arange(1, 2_000_001))
        start = time.perf_counter()
        Block(block).write_point_layer("mass_points", small, FlatModel(), 1, 0.0)
        rows.append(
            {
                "step": "write the display layer of 2000000 points (GeoPackage: sqlite3 rows + OGR R-tree; a "
                f"uniform {points_store.DISPLAY_POINTS} of them shown)",
                "seconds": time.perf_counter() - start,
            }
        )
    return rows


if __name__ == "__main__":
    for r in run():
        print(f"{r['step']}: {r['seconds']:.3f} s")
