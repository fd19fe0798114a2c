"""DSMs from matched real Pleiades pixels, shared by the real-data DSM tests of region growing
(test_dsm_real.py) and of the coarse-to-fine matcher (test_coarse_to_fine_real.py): intersection
(surface.intersection), TIN gridding (surface.tin_dem), the comparison with the SRTM tile of the
Ventoux pair, the common footprint of the triplet, the pairs' differences on one lattice, and the
triplet DSMs of one matcher with the supplied and the bias-adjusted RPCs (pleiades_scene's image
order), and the points dense matching refined. test_dsm_real.py's docstring gives the reasons for the
choices."""

import time

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.bundle import AdjustmentSettings, adjust
from pushbroom.algorithms.adjustment.observations import tie_observations
from pushbroom.algorithms.crs import reproject, transform, wgs84
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.imagery import Image, as_image
from pushbroom.algorithms.matching.points import MultiPoints
from pushbroom.algorithms.matching.tiepoints import select_tie_points
from pushbroom.algorithms.quality.height_differences import Reference, dem_differences
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from pushbroom.algorithms.surface.point_input import PointSet
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_dem import DemParams, interpolate_dem, write_dem
from tests.helpers.pleiades_scene import LABELS, NAMES, in_order, triplet_models

#: region growing on the Ventoux pair: nodes every VENTOUX_STEP px (1 m), the DSM asserted at VENTOUX_CELL m
VENTOUX_STEP, VENTOUX_CELL = 2, 2.0
#: region growing's triplet DSM: nodes every TRIPLET_STEP px (1.5 m), CELL m cells, gaps where a triangle is
#: longer than RG_MAX_EDGE m (two node spacings)
TRIPLET_STEP, CELL, RG_MAX_EDGE = 3, 0.5, 3.0
#: the three pairs, as indices into the combination order (img_02, img_01, img_03)
PAIRS = ((0, 1), (0, 2), (1, 2))
#: the bias adjustment of test_adjust_pleiades: shifts of img_01 and img_03 free (img_02 fixed), 10 px priors
OTHERS = [f"{LABELS[i]} {k}" for i in (2, 3) for k in ("A0", "B0")]
PRIORS = {"bias:shift": 10.0}


def dense_points(images, models, names, folder, heights, params=None):
    """(MultiPoints of every dense point, seconds of the matching): dense matching (DenseParams `params`, default
    the defaults; 2 threads) of `images` (paths or Image) with `models` over `heights` (h_min, h_max) in the work
    `folder`."""
    t = time.perf_counter()
    parts, _ = match_dense_tiles(
        [as_image(p) for p in images],
        models,
        folder,
        names=names,
        params=params or DenseParams(),
        height_range=tuple(heights),
        execution=Execution("threads", 2),
    )
    seconds = time.perf_counter() - t
    return (
        MultiPoints(np.concatenate([p.points for p in parts]), np.concatenate([p.observations for p in parts])),
        seconds,
    )


def refined(points):
    """The points of dense MultiPoints that LSM refined in every position."""
    keep = points.points[np.isfinite(points.points["rho_min"])]
    return MultiPoints(keep, points.observations[np.isin(points.observations["point_id"], keep["id"])])


def refined_dense_points(images, models, names, folder, heights, params=None):
    """(MultiPoints of the dense points LSM refined in every position, seconds of the matching): `dense_points`,
    `refined`."""
    points, seconds = dense_points(images, models, names, folder, heights, params)
    return refined(points), seconds


def dense_pair_of_triplet(points, k):
    """The dense MultiPoints of the pair (reference, image k + 1), k = 1 or 2, from a triplet's (block ids 1, 2,
    3): the points that pair matched, with its two observations (image k + 1's as image 2). Dense matching
    matches each pair of a triplet as it matches the pair alone (dense_strategy.tile_points; tested in
    tests/algorithms/dense/test_dense_strategy.py), so these are the pair's own points, numbered otherwise; but
    where the other pair's bias test (dense/refine.py) kept a node's positions semi-global, both pairs' are
    (a few of the real nodes: studies/README.md#dense_bias_test)."""
    obs = points.observations
    mine = obs[obs["image_id"] == k + 1]
    keep = points.points[np.isin(points.points["id"], mine["point_id"])].copy()
    pair = obs[np.isin(obs["point_id"], keep["id"]) & np.isin(obs["image_id"], (1, k + 1))].copy()
    pair["image_id"][pair["image_id"] == k + 1] = 2
    rho = np.full(len(keep), np.nan, np.float32)
    rho[np.searchsorted(keep["id"], mine["point_id"])] = mine["rho"]
    keep["group"], keep["rho_min"], keep["rho_a"], keep["rho_b"] = 1, rho, rho, np.nan
    return MultiPoints(keep, pair)


def cut(models, observations, which=None):
    """Intersection of the observations (OBS_DTYPE) of the points `which` (ids; default all) with
    `models` {block image id: model}."""
    obs = observations if which is None else observations[np.isin(observations["point_id"], which)]
    return intersect(models, Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]))


def dsm(result, srs, cell, max_edge=None):
    """DemResult of the converged points of an Intersection, in `srs`, ellipsoidal heights."""
    ok = result.ok
    x, y = reproject(result.lon[ok], result.lat[ok], wgs84(), srs)
    return interpolate_dem(PointSet(x, y, result.h[ok], srs), DemParams(cell=cell, crs=srs, max_edge=max_edge))


def on_grid(dem, grid):
    """dem.heights placed on `grid`: same cell, both on the lattice of multiples of it."""
    dj, di = (dem.grid.x0 - grid.x0) / grid.cell, (grid.y0 - dem.grid.y0) / grid.cell
    assert dem.grid.cell == grid.cell and dj == round(dj) and di == round(di), (dem.grid, grid)
    dj, di = round(dj), round(di)
    rows, cols = dem.grid.shape
    i0, i1, j0, j1 = max(di, 0), min(di + rows, grid.rows), max(dj, 0), min(dj + cols, grid.cols)
    out = np.full(grid.shape, np.nan)
    out[i0:i1, j0:j1] = dem.heights[i0 - di : i1 - di, j0 - dj : j1 - dj]
    return out


def stats_row(label, s):
    """Stats as a row of a figures table (m)."""
    return {"": label, "N": s.n, "median": s.median, "NMAD": s.nmad, "mean": s.mean, "RMS": s.rms, "95 % |dh|": s.q95}


def srtm_comparison(result, srtm, cells, cell, folder):
    """DSMs of an Intersection at each of `cells` (m), written to `folder`, against the SRTM tile
    `srtm` (EGM96 heights made ellipsoidal: quality.height_differences). Returns a dict: "dems" and
    "stats" (of DSM - SRTM) per cell; for `cell`: "diff" (HeightDifferences), "geoid" (the same DSM
    against the SRTM taken as ellipsoidal, minus "diff": N(EGM96) per cell), "plane" (least-squares
    plane of dh: offset, m/m east, m/m north), "flat" (dh without it, per cell of "diff") and "detrended" (its
    Stats)."""
    srs = output_srs(None, result.lon[result.ok], result.lat[result.ok])
    out = {"dems": {}, "stats": {}}
    for c in cells:
        dem = out["dems"][c] = dsm(result, srs, c)
        path = folder / f"dsm_{c:g}m.tif"
        write_dem(dem, path)
        diff = dem_differences(path, Reference(srtm, "orthometric"))
        out["stats"][c] = summarize(diff.dh)
        if c == cell:
            out["diff"] = d = diff
            out["geoid"] = dem_differences(path, Reference(srtm, "ellipsoidal")).dh - d.dh
    a = np.column_stack([np.ones_like(d.x), d.x - d.x.mean(), d.y - d.y.mean()])
    out["plane"], *_ = np.linalg.lstsq(a, d.dh, rcond=None)
    out["flat"] = d.dh - a @ out["plane"]
    out["detrended"] = summarize(out["flat"])
    return out


def report_srtm_comparison(comparison, figures):
    """Report an srtm_comparison: DSM - SRTM per cell size, the plane of dh and dh without it."""
    figures.table(
        "DSM - SRTM (EGM96 -> ellipsoidal) (m)",
        [stats_row(f"{c:g} m DSM", s) for c, s in comparison["stats"].items()]
        + [stats_row("without the plane", comparison["detrended"])],
    )
    figures.report("plane of dh, east and north", comparison["plane"][1:], "m/m")


def footprint_mask(grid, srs, models, height):
    """Cells of `grid` whose centre at `height` lies inside every model's image."""
    x, y = grid.centres()
    ll = transform(srs, wgs84(), np.column_stack([x.ravel(), y.ravel()]), "the DSM cells")
    inside = np.ones(x.size, bool)
    for m in models:
        c, r = m.ground_to_image(ll[:, 0], ll[:, 1], np.full(x.size, height))
        inside &= (c >= 0) & (c <= m.size[0]) & (r >= 0) & (r <= m.size[1])
    return inside.reshape(grid.shape)


def pair_differences(dems, grid, inside):
    """{(pair, pair): Stats of their DSMs' differences over `inside` cells of `grid`}."""
    on = {p: on_grid(dems[p], grid) for p in PAIRS}
    return {(p, q): summarize((on[p] - on[q])[inside]) for i, p in enumerate(PAIRS) for q in PAIRS[i + 1 :]}


def pair_name(pair):
    return "-".join(NAMES[k] for k in pair)


def build_triplet_dsms(triplet, match, cell, max_edge, folder, log):
    """The triplet (pleiades_triplet paths) matched by match(images, models, names) -> MultiPoints
    and each pair matched on its own by the same function: the pairs' DSMs with the supplied RPCs
    ("before") and the bias-adjusted ones ("after": the adjustment of OTHERS / PRIORS on tie points of
    the triplet's matching), and the DSM of the triplet's three-ray points (group >= 2, adjusted
    RPCs; "three": their Intersection), written to `folder`/dsm.tif ("path"). Also "points", "srs",
    "height", "models" (supplied RPCs, combination order), "seconds" (matching) and "sigma0"; the timings and counts
    are appended to log.messages."""
    t0 = time.perf_counter()
    paths = in_order(triplet)
    images = [Image(p) for p in paths]
    models = [sensors.load(p) for p in paths]
    points = match(images, models, NAMES)
    pairs = {(a, b): match([images[a], images[b]], [models[a], models[b]], [NAMES[a], NAMES[b]]) for a, b in PAIRS}
    t_match = time.perf_counter() - t0
    three = points.points["id"][points.points["group"] >= 2]
    supplied = {k + 1: m for k, m in enumerate(models)}
    first = cut(supplied, points.observations, three)
    srs = output_srs(None, first.lon[first.ok], first.lat[first.ok])
    height = float(np.nanmedian(first.h))
    adjusted = adjust(
        triplet_models(triplet),
        tie_observations(select_tie_points(points)),
        OTHERS,
        names=LABELS,
        height=height,
        settings=AdjustmentSettings(priors=PRIORS),
    )
    out = {
        "points": points,
        "srs": srs,
        "height": height,
        "models": models,
        "seconds": t_match,
        "sigma0": adjusted.sigma0,
    }
    for label, block in (("before", supplied), ("after", adjusted.parameters.models)):
        out[label] = {
            (a, b): dsm(cut({1: block[a + 1], 2: block[b + 1]}, pairs[a, b].observations), srs, cell, max_edge)
            for a, b in PAIRS
        }
    out["three"] = cut(adjusted.parameters.models, points.observations, three)
    out["triplet"] = dsm(out["three"], srs, cell, max_edge)
    out["path"] = folder / "dsm.tif"
    write_dem(out["triplet"], out["path"])
    log.messages += [
        f"triplet: {len(points)} points {points.group_counts()}; pairs: "
        + ", ".join(f"{NAMES[a]}-{NAMES[b]} {len(p)}" for (a, b), p in pairs.items())
        + f"; matching {t_match:.1f} s, all {time.perf_counter() - t0:.1f} s; adjustment sigma_0 "
        f"{adjusted.sigma0:.3f}"
    ]
    return out


def check_pair_consistency(dsms, title, max_median, max_nmad, figures):
    """Report (`figures`) the differences of the pair DSMs of `build_triplet_dsms` before and after the bias
    adjustment (title: what matched them) and assert that afterwards each pair covers more than half
    of the common footprint and agrees to |median| < max_median (and < 0.2 x the largest median
    before) and NMAD < max_nmad (m)."""
    grid = dsms["triplet"].grid
    inside = footprint_mask(grid, dsms["srs"], dsms["models"], dsms["height"])
    stats = {}
    for label in ("before", "after"):
        stats[label] = pair_differences(dsms[label], grid, inside)
        covered = {p: np.isfinite(on_grid(dsms[label][p], grid))[inside].mean() for p in PAIRS}
        figures.report(
            f"{title} pair DSMs {label} the bias adjustment, coverage of the footprint",
            {pair_name(p): 100 * c for p, c in covered.items()},
            "%",
        )
        figures.table(
            f"{title} pair DSMs {label} the bias adjustment, differences (m)",
            [stats_row(f"({pair_name(p)}) - ({pair_name(q)})", s) for (p, q), s in stats[label].items()],
        )
    before = max(abs(s.median) for s in stats["before"].values())
    for key, s in stats["after"].items():
        assert s.n > 0.5 * inside.sum(), (key, s)
        assert abs(s.median) < max_median and abs(s.median) < 0.2 * before and s.nmad < max_nmad, (key, s)
