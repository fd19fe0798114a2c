"""Issue 39: the Ventoux pair's dense DSM against SRTM went from 3.53 m (NMAD without the west-east plane, 2026-11-27)
to 3.58 m while its refined points grew from 36 815 to 44 493. Is it worse, or does it cover harder ground?

The Ventoux pair (../shared/data), dense matching as tests/real/test_dense_real.py runs it (refined points only, over
the RPCs' height range; 2 threads), with the settings of 2026-11-27 (plain LSM: no robust weights, no wide window, the
largest shift 0.5 px, no bias test) and with today's defaults; each cloud's 2 m DSM (TIN) against SRTM
(tests/helpers/real_dsm.srtm_comparison, dh without each DSM's least-squares plane); then the NMAD of each on the cells
both DSMs have, and on the cells only one has."""

import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.quality.statistics import summarize
from studies.sim_dense import SHARED
from tests.helpers.real_dsm import cut, refined_dense_points, srtm_comparison

PAIR = [SHARED / "pleiades_pair_ventoux" / f"{side}_image.tif" for side in ("left", "right")]
CELL = 2.0
SETTINGS = {
    "2026-11-27 (plain LSM, 0.5 px)": DenseParams(robust=False, wide_template=0, max_shift=0.5, bias_bound=0.0),
    "today's defaults": DenseParams(),
}


def main() -> None:
    if not all(p.exists() for p in PAIR):
        print(f"the Ventoux pair is not in {SHARED}")
        return
    models = [sensors.load(p) for p in PAIR]
    srtm = str(PAIR[0].with_name("N44E005.hgt"))
    cells = {}
    for label, params in SETTINGS.items():
        folder = Path(tempfile.mkdtemp())
        points, _ = refined_dense_points(
            PAIR, models, [p.stem for p in PAIR], folder / "dense", models[0].height_range, params
        )
        (folder / "dsm").mkdir()
        comparison = srtm_comparison(
            cut({1: models[0], 2: models[1]}, points.observations), srtm, (CELL,), CELL, folder / "dsm"
        )
        d = comparison["diff"]
        cells[label] = (d.x, d.y, comparison["flat"])
        print(
            f"{label}: {len(points)} refined points, {len(d.dh)} cells, NMAD without the plane "
            f"{comparison['detrended'].nmad:.2f} m"
        )
    # the grids' origins follow each cloud's extent: a cell of one is "the same" as the other's nearest centre
    # within half a cell in x and y
    (xa, ya, _), (xb, yb, _) = cells.values()
    distance, nearest = cKDTree(np.column_stack([xb, yb])).query(np.column_stack([xa, ya]), p=np.inf)
    in_a = distance <= CELL / 2
    in_b = np.zeros(xb.size, bool)
    in_b[nearest[in_a]] = True
    print(f"\ncells both DSMs have: {int(in_a.sum())}")
    print("| settings | NMAD without the plane, the common cells | its other cells: count, NMAD |")
    print("|---|---|---|")
    for (label, (_, _, flat)), common in zip(cells.items(), (in_a, in_b)):
        rest = flat[~common]
        other = f"{rest.size}, {summarize(rest).nmad:.2f} m" if rest.size > 2 else f"{rest.size}"
        print(f"| {label} | {summarize(flat[common]).nmad:.2f} m | {other} |")


if __name__ == "__main__":
    main()
