"""The terrain height found by matching (issue 22, matching/height_search.py) on real Pleiades pixels.

With no DEM and no height, the range found must hold the terrain the images see (the region growing points
matched over the RPCs' whole validity range, the session's fixtures of tests/real/conftest.py, are the
reference), be far narrower than that validity range, and give the DSM a user gets with the terrain's
height typed in (that height +- 500 m; on the triplet, the DSM over the whole validity range): both DSMs are
printed, and their difference must be the matching's noise (median and NMAD of a few cm). Likewise for dense
matching (algorithms/dense) on the Ventoux pair: the DSMs of its LSM-refined points with the range found and
with the height given. On the triplet, dense matching over the range found is test_dense_real's (the
session's dense_triplet_dsms)."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.height_search import search_heights
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import match_block
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.surface.pointcloud import output_srs
from tests.helpers.pleiades_scene import NAMES, in_order
from tests.helpers.real_dsm import (
    CELL,
    RG_MAX_EDGE,
    TRIPLET_STEP,
    VENTOUX_CELL,
    VENTOUX_STEP,
    cut,
    dsm,
    on_grid,
    refined_dense_points,
    srtm_comparison,
    stats_row,
)

#: m: the two DSMs' difference where both are defined (the same points matched from other seeds)
MAX_MEDIAN, MAX_NMAD = 0.05, 0.10


def matched(paths, models, names, step, heights):
    """Intersection (supplied RPCs) of the points region growing matched in all images over `heights`."""
    points = match_block(
        [Image(p) for p in paths], models, names=names, params=GrowParams(step=step), height_range=heights, workers=2
    )
    return cut(
        {k + 1: m for k, m in enumerate(models)},
        points.observations,
        points.points["id"][points.points["group"] >= len(paths) - 1],
    )


def dense_matched(paths, models, names, heights, folder):
    """Intersection (supplied RPCs) of the dense points LSM refined, matched over `heights` (a range, or one
    height: +- 500 m as the block's)."""
    if np.ndim(heights) == 0:
        heights = (heights - 500.0, heights + 500.0)
    points, _ = refined_dense_points(paths, models, names, folder, heights)
    return cut({k + 1: m for k, m in enumerate(models)}, points.observations)


def given_height(reference):
    """The terrain's median height (of `reference`, the points matched over the RPCs' validity range), as a user
    would type it in."""
    return float(np.median(reference.h[reference.ok]))


def found_and_given(paths, names, step, reference, folder=None):
    """(HeightSearch, the height given, {"found" / "given": Intersection}) for the range found and for the
    terrain's median height (given_height) typed in (+- 500 m); region growing at `step`, or dense matching in
    `folder` where given."""
    models = [sensors.load(p) for p in paths]
    found = search_heights(paths, models, names)
    given = given_height(reference)
    if folder is not None:
        return (
            found,
            given,
            {
                k: dense_matched(paths, models, names, h, folder / k)
                for k, h in (("found", found.height_range), ("given", given))
            },
        )
    return (
        found,
        given,
        {k: matched(paths, models, names, step, h) for k, h in (("found", found.height_range), ("given", given))},
    )


def check_range(found, reference, figures, title):
    h = reference.h[reference.ok]
    lo, hi = np.percentile(h, (0.5, 99.5))
    figures.report(
        f"{title}: heights found (range, median, points, rejected)",
        [*found.height_range, found.median, found.points, found.rejected],
        "m",
    )
    figures.report(f"{title}: terrain (0.5 / 99.5 % of the points over the RPC's {found.searched} m)", [lo, hi], "m")
    assert found.height_range[0] <= lo and hi <= found.height_range[1], (found, lo, hi)
    span = found.searched[1] - found.searched[0]
    assert found.height_range[1] - found.height_range[0] < 0.5 * span, found


def compare_dsms(a, b, figures, title, against="the height given"):
    """The DSM `b` with the range found against the DSM `a` matched over `against`."""
    grid = a.grid
    diff = summarize((on_grid(b, grid) - a.heights).ravel())
    figures.table(f"{title}: DSM with the range found minus DSM over {against} (m)", [stats_row("difference", diff)])
    assert diff.n > 1000 and abs(diff.median) < MAX_MEDIAN and diff.nmad < MAX_NMAD, diff


@pytest.mark.slow
def test_triplet_height_found_gives_the_dsm_of_the_whole_range(
    pleiades_triplet, region_growing_triplet_dsms, triplet_heights_found, figures
):
    """Region growing over the range found against the session's region growing over the RPCs' whole valid range
    (the reference); dense matching over the range found is test_dense_real's triplet (the session's
    dense_triplet_dsms), and its found-against-given comparison the Ventoux pair's below."""
    paths, models = in_order(pleiades_triplet), region_growing_triplet_dsms["models"]
    points = region_growing_triplet_dsms["points"]
    reference = cut(
        {k + 1: m for k, m in enumerate(models)}, points.observations, points.points["id"][points.points["group"] >= 2]
    )
    found = triplet_heights_found
    out = {
        "over the RPCs' valid range": reference,
        "found": matched(paths, models, list(NAMES), TRIPLET_STEP, found.height_range),
    }
    title = "Pleiades triplet, region growing"
    check_range(found, reference, figures, title)
    srs = output_srs(None, reference.lon[reference.ok], reference.lat[reference.ok])
    dems = {k: dsm(v, srs, CELL, RG_MAX_EDGE) for k, v in out.items()}
    for k, dem in dems.items():
        figures.report(
            f"{title}, 0.5 m DSM of the points, heights {k}: cells, median height",
            [int(np.isfinite(dem.heights).sum()), float(np.nanmedian(dem.heights))],
            "m",
        )
    compare_dsms(*dems.values(), figures, title, "the RPCs' valid range")


@pytest.mark.parametrize("matcher", ["region growing", "dense"])
def test_ventoux_height_found_gives_the_dsm_of_the_height(
    ventoux_pair, ventoux_region_growing, figures, tmp_path, matcher
):
    (tmp_path / "given").mkdir()
    (tmp_path / "found").mkdir()
    reference = ventoux_region_growing[1]
    found, given, out = found_and_given(
        ventoux_pair,
        [p.stem for p in ventoux_pair],
        VENTOUX_STEP,
        reference,
        tmp_path / "dense" if matcher == "dense" else None,
    )
    title = f"Ventoux pair, {matcher}"
    check_range(found, reference, figures, title)
    figures.report(f"{title}: the height given", given, "m")
    srtm = str(ventoux_pair[0].with_name("N44E005.hgt"))
    comparisons = {
        k: srtm_comparison(out[k], srtm, (VENTOUX_CELL,), VENTOUX_CELL, tmp_path / k) for k in ("given", "found")
    }
    figures.table(
        f"{title}, 2 m DSM - SRTM (EGM96 -> ellipsoidal) (m)",
        [stats_row(f"height {k}", c["stats"][VENTOUX_CELL]) for k, c in comparisons.items()]
        + [stats_row(f"height {k}, without the plane", c["detrended"]) for k, c in comparisons.items()],
    )
    compare_dsms(comparisons["given"]["dems"][VENTOUX_CELL], comparisons["found"]["dems"][VENTOUX_CELL], figures, title)
