"""Issue 39: on the Pleiades triplet, is the dense DSM's precision raster true? The pair differences' spread over the
cells' predicted sigma should be 0.8-1.25. And the RPC sensors' precision factors (precision.RPC), fitted on them.

The triplet (img_02, img_01, img_03; ../shared/data) matched densely (default DenseParams, 2 threads, over the heights
the height search finds for it: 40-535 m), its pairs img_02-img_01 and img_02-img_03 taken from it
(tests/helpers/real_dsm.dense_pair_of_triplet) and img_01-img_03 matched on its own. Each pair's refined points
intersected with the supplied RPCs and the product's image sigmas (dense/precision.image_sigmas), their spread term
added (precision.with_spread over surface/local_spread.py, as intersectpoints does), and the per-cell DSM of the DEM
step (cell_dem.cells_on_grid: 0.5 m, k 3, FALLBACK off, RADIUS 1, the points' tiers) with its precision raster. For
each two pairs, over the cells both measure from their own points: d = h_p - h_q less its median (the RPCs' bias
differs between the pairs), and NMAD(d / sqrt(sigma_p^2 + sigma_q^2)) (1: the rasters are true, were the pairs'
errors independent) beside NMAD(d) / median(sqrt(sigma_p^2 + sigma_q^2)); again without the spread term; then F_2
and C fitted (`fit`), beside precision.RPC, the product's."""

import tempfile
from collections.abc import Iterator

import numpy as np

from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.matching.points import MultiPoints
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid, point_tiers
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from pushbroom.algorithms.surface.local_spread import local_metres
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from studies.sim_dense import TRIPLET, TRIPLET_HEIGHTS, triplet_points, with_template_spread
from tests.helpers.real_dsm import dense_pair_of_triplet, dense_points

CELL = 0.5


def pair_cloud(points: MultiPoints, models: list) -> dict:
    """Refined dense points (block ids 1, 2[, 3]: a pair's, or a triplet's with every ray) intersected with `models`
    (in the ids' order): lon, lat, h, sigma_h, tier."""
    keep = points.points[np.isfinite(points.points["rho_min"])]
    obs = points.observations[np.isin(points.observations["point_id"], keep["id"])]
    sigma = precision.image_sigmas(keep, obs, IMAGE_SIGMA, precision.RPC.factors)
    res = intersect(
        dict(enumerate(models, start=1)),
        Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"], sigma),
    )
    ok = res.ok
    lon, lat, h = res.lon[ok], res.lat[ok], res.h[ok]
    x, y = local_metres(lon, lat, (float(np.mean(lon)), float(np.mean(lat))))
    every = np.ones(h.size, bool)  # the pair's refined points only
    sigma_h, spread = with_template_spread(res.sigma[ok, 2], x, y, h, every, models[0], precision.RPC.spread)
    slot = np.searchsorted(keep["id"], res.point[ok])
    tier = point_tiers(keep["rho_min"][slot], res.rays[ok])
    return {
        "lon": lon,
        "lat": lat,
        "h": h,
        "sigma": sigma_h,
        "rays": res.sigma[ok, 2],
        "unit": res.sigma[ok, 2] / precision.RPC.factors[2],
        "spread": np.nan_to_num(spread),
        "tier": tier,
    }


def triplet_pairs() -> tuple[list, MultiPoints, dict] | None:
    """(models, the triplet's dense points, {pair: its cloud (pair_cloud)}) of the three pairs (module docstring);
    None, and said, where the data are absent."""
    matched = triplet_points()
    if matched is None:
        return None
    models, triplet = matched
    third, _ = dense_points(TRIPLET[1:], models[1:], ["img_01", "img_03"], tempfile.mkdtemp(), TRIPLET_HEIGHTS)
    return (
        models,
        triplet,
        {
            "img_02-img_01": pair_cloud(dense_pair_of_triplet(triplet, 1), models[:2]),
            "img_02-img_03": pair_cloud(dense_pair_of_triplet(triplet, 2), [models[0], models[2]]),
            "img_01-img_03": pair_cloud(third, models[1:]),
        },
    )


def common_grid(clouds: dict, srs: object) -> tuple[dict, Grid]:
    """({name: (x, y) of its points in `srs`}, the CELL m Grid over all the clouds {name: pair_cloud})."""
    xy = {k: reproject(c["lon"], c["lat"], wgs84(), srs) for k, c in clouds.items()}
    x0 = min(float(v[0].min()) for v in xy.values())
    y0 = max(float(v[1].max()) for v in xy.values())
    cols = int((max(float(v[0].max()) for v in xy.values()) - x0) / CELL) + 1
    rows = int((y0 - min(float(v[1].min()) for v in xy.values())) / CELL) + 1
    return xy, Grid(x0, y0, CELL, cols, rows)


def main() -> None:
    found = triplet_pairs()
    if found is None:
        return
    _, _, clouds = found
    first = clouds["img_02-img_01"]
    xy, grid = common_grid(clouds, output_srs(None, first["lon"], first["lat"]))
    settings = CellSettings(k=3.0, fallback=False, radius=1)
    for term in ("sigma", "rays"):
        dems = {
            k: cells_on_grid(xy[k][0], xy[k][1], c["h"], c[term], grid, settings, tier=c["tier"])
            for k, c in clouds.items()
        }
        print(f"\n{'the product' if term == 'sigma' else 'without the spread term'}:")
        compare(dems)
    # the cells' two terms at F = C = 1 (a cell's precision is the RMS of its points' sigmas: cell_dem.py)
    parts = {
        term: {
            k: cells_on_grid(xy[k][0], xy[k][1], c["h"], c[term], grid, settings, tier=c["tier"])
            for k, c in clouds.items()
        }
        for term in ("unit", "spread")
    }
    f, c = fit(dems, parts["unit"], parts["spread"])
    print(f"\nfitted on the three comparisons: F_2 = {f:.2f}, C = {c:.2f} (precision.RPC: {precision.RPC})")


def common_differences(dems: dict) -> Iterator[tuple[str, str, np.ndarray, np.ndarray]]:
    """Per two pairs of the per-cell DSMs `dems` {pair: cell_dem.Cells}: their names, the cells both measure from
    their own points with a precision, and d there, their heights' difference less its median."""
    names = list(dems)
    for a in range(3):
        for b in range(a + 1, 3):
            p, q = dems[names[a]], dems[names[b]]
            both = (p.ring == 0) & (q.ring == 0) & np.isfinite(p.heights) & np.isfinite(q.heights)
            both &= np.isfinite(p.precision) & np.isfinite(q.precision)
            d = (p.heights - q.heights)[both].astype(float)
            yield names[a], names[b], both, d - np.median(d)


def fit(dems: dict, unit: dict, spread: dict) -> tuple[float, float]:
    """(F, C) that make NMAD(d / sigma) closest to 1 (least squares of its logarithm) in each fifth of the cells
    by the spread term's share, over the three comparisons: sigma^2 = F^2 (R_p^2 + R_q^2) + C^2 (S_p^2 + S_q^2) with
    R, S a cell's two terms at F = C = 1."""
    rows = []
    for a, b, both, d in common_differences(dems):
        r2, s2 = ((t[a].precision ** 2 + t[b].precision ** 2)[both].astype(float) for t in (unit, spread))
        rows.append((d, r2, s2))
    d, r2, s2 = (np.concatenate([r[i] for r in rows]) for i in range(3))
    share = s2 / (r2 + s2)
    bins = np.digitize(share, np.quantile(share, [0.2, 0.4, 0.6, 0.8]))
    best = (np.inf, 1.0, 1.0)
    for f in np.arange(0.5, 3.01, 0.05):
        for c in np.arange(0.0, 1.01, 0.02):
            z = d / np.sqrt(f * f * r2 + c * c * s2)
            cost = sum(np.log(1.4826 * np.median(np.abs(z[bins == k]))) ** 2 for k in range(5))
            best = min(best, (cost, f, c))
    return best[1], best[2]


def compare(dems: dict) -> None:
    """The table of the module docstring for the per-cell DSMs `dems` {pair: cell_dem.Cells}."""
    print("| pairs | cells | NMAD(d) m | median predicted sigma of d, m | NMAD(d / sigma) | ratio of the two |")
    print("|---|---|---|---|---|---|")
    for a, b, both, d in common_differences(dems):
        s = np.hypot(dems[a].precision[both], dems[b].precision[both]).astype(float)
        nmad = 1.4826 * np.median(np.abs(d))
        z = d / s
        print(
            f"| {a} vs {b} | {both.sum()} | {nmad:.3f} | {np.median(s):.3f} | "
            f"{1.4826 * np.median(np.abs(z - np.median(z))):.2f} | {nmad / np.median(s):.2f} |"
        )


if __name__ == "__main__":
    main()
