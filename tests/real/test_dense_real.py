"""Dense matching (issue 22, algorithms/dense) on real Pleiades pixels, next to region growing.

Ventoux pair: the 2 m DSM of the dense points LSM refined against the SRTM tile (EGM96 made ellipsoidal),
beside region growing's (the session fixture, nodes every 2 px), both as TINs of their points
(real_dsm.srtm_comparison). Pleiades triplet (the session's dense_triplet_dsms, matched over the terrain
heights found by matching, as a block created without a DEM or a height is): the refined dense points of
the triplet and of each pair alone, their 0.5 m DSMs' coverage of the common footprint and the pairs'
agreement with the supplied and the bias-adjusted RPCs (real_dsm: the adjustment on tie points of the
triplet's dense points), beside region growing's; issue 22 asks 98 % and NMAD 0.25 m: the figures are
printed, the bounds asserted are today's, as regression bounds."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from tests.helpers.real_dsm import (
    VENTOUX_CELL,
    cut,
    footprint_mask,
    pair_differences,
    pair_name,
    refined_dense_points,
    srtm_comparison,
    stats_row,
)


def test_ventoux_dense_dsm_against_srtm_beside_region_growing(ventoux_pair, ventoux_region_growing, figures, tmp_path):
    models = [sensors.load(p) for p in ventoux_pair]
    points, seconds = refined_dense_points(
        ventoux_pair, models, [p.stem for p in ventoux_pair], tmp_path / "dense", models[0].height_range
    )
    result = cut({1: models[0], 2: models[1]}, points.observations)
    (tmp_path / "dsm").mkdir()
    dense = srtm_comparison(
        result, str(ventoux_pair[0].with_name("N44E005.hgt")), (VENTOUX_CELL,), VENTOUX_CELL, tmp_path / "dsm"
    )
    rg = ventoux_region_growing[2]
    figures.report("Ventoux dense: refined points, matching", [len(points), seconds], "points, s")
    figures.table(
        "Ventoux pair, 2 m DSM - SRTM (m): dense (refined points) and region growing",
        [
            stats_row("dense", dense["stats"][VENTOUX_CELL]),
            stats_row("region growing", rg["stats"][VENTOUX_CELL]),
            stats_row("dense, without the plane", dense["detrended"]),
            stats_row("region growing, without the plane", rg["detrended"]),
        ],
    )
    d, r = dense["stats"][VENTOUX_CELL], rg["stats"][VENTOUX_CELL]
    assert d.n > 0.9 * r.n and abs(d.median - r.median) < 1.0
    assert dense["detrended"].nmad < 1.1 * rg["detrended"].nmad, (dense["detrended"], rg["detrended"])


@pytest.mark.slow
def test_triplet_dense_coverage_and_pair_agreement(
    dense_triplet_dsms, triplet_heights_found, region_growing_triplet_dsms, figures
):
    rows, coverage = [], {}
    for label, d in (("dense", dense_triplet_dsms), ("region growing", region_growing_triplet_dsms)):
        grid = d["triplet"].grid
        inside = footprint_mask(grid, d["srs"], d["models"], d["height"])
        coverage[label] = float(np.isfinite(d["triplet"].heights)[inside].mean())
        for rpcs in ("before", "after"):
            for (p, q), s in pair_differences(d[rpcs], grid, inside).items():
                rows.append(
                    {
                        "matcher": label,
                        "RPCs": "supplied" if rpcs == "before" else "bias-adjusted",
                        "pairs": f"{pair_name(p)} vs {pair_name(q)}",
                        "median": s.median,
                        "NMAD": s.nmad,
                        "N": s.n,
                    }
                )
    figures.report(
        "Pleiades triplet, dense matching's height range (found by matching)",
        list(triplet_heights_found.height_range),
        "m",
    )
    figures.report(
        "Pleiades triplet, 0.5 m DSM coverage of the common footprint: dense (refined), region growing",
        [100 * coverage["dense"], 100 * coverage["region growing"]],
        "%",
        "issue 22 asks 98 %",
    )
    figures.table("Pleiades triplet: the pair DSMs' differences (m)", rows)
    figures.report("dense matching", dense_triplet_dsms["log"])
    assert coverage["dense"] > max(0.8, coverage["region growing"])
    after = [r for r in rows if r["matcher"] == "dense" and r["RPCs"] == "bias-adjusted"]
    assert max(r["NMAD"] for r in after) < 0.6 and max(abs(r["median"]) for r in after) < 0.2, rows
