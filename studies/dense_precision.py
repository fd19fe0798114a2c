"""Calibration of the refined dense points' precision (dense/precision.py). On a 3 km simulated SPOT 5 triplet
(HRG, HRS1, HRS2; the DSM's height range +- 100 m), dense matching with the default DenseParams but 256 px
tiles; the refined points (every matched position refined by LSM) intersected with the TRUE models (so the error
is the matching's alone) with dense/precision.image_sigmas at F = 1, and the local spread of their heights
(surface/local_spread.py, R = precision.spread_radius). F_2, F_3 and C are the least-squares fit of dh^2 =
F_k^2 sigma_h,rays^2 + C^2 s^2 over the open classes (bare fields, crops) of the calibration scene. Then per
number of rays and open class, over all their points and over those at least 50 m (the template's half-width)
from forest, city or water: RMS(dh) / RMS(sigma_h) and the NMAD of dh / sigma_h (1 is calibrated), with the
product's constants, and with F = 1 and no spread term.

Scenes: SceneConfig.small() (seed 1, the calibration) and, to check that the constants carry over, another
seed and centre (seed 2, 4 km west: small fields among forest)."""

import tempfile

import numpy as np
from osgeo import gdal
from scipy import ndimage
from scipy.optimize import nnls

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.matching.points import SEMI_GLOBAL
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.local_spread import local_metres, local_spread
from studies.dense_fusion import NAMES

OPEN = {2: "bare", 3: "crops"}
CLASS_NAMES = {**OPEN, 4: "forest", 5: "city"}
INTERIOR = 50.0  # m from forest, city or water
SCENES = {
    "seed 1 (calibration)": SceneConfig.small(),
    "seed 2, 4 km west": SceneConfig.small(seed=2, centre_lon=-84.235),
}


def scene_errors(config):
    """Per refined dense point intersected: dh against the true DSM, sigma_h at F = 1, rays, the local spread,
    the class and the distance (m) to the nearest forest, city or water cell."""
    paths = simulate_scene(config, tempfile.mkdtemp() + "/scene")
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    truth = {k: sensors.load(paths["truth_metadata"][n]) for k, n in enumerate(NAMES, start=1)}
    dsm = read_dem(paths["dsm"])
    lo, hi = dsm.height_range
    parts, _ = match_dense_tiles(
        images,
        models,
        tempfile.mkdtemp() + "/dense",
        params=DenseParams(tile=256),
        height_range=(lo - 100.0, hi + 100.0),
        execution=Execution("threads", 2),
    )
    points = np.concatenate([p.points for p in parts])
    obs = np.concatenate([p.observations for p in parts])
    keep = points["id"][precision.refined_dense(points)]
    points, obs = points[np.isin(points["id"], keep)], obs[np.isin(obs["point_id"], keep)]
    sigma = precision.image_sigmas(points, obs, np.nan, {2: 1.0, 3: 1.0})
    res = intersection.intersect(
        truth,
        intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"], sigma),
        h0=0.5 * (lo + hi),
    )
    ok = res.ok
    lon, lat, h = res.lon[ok], res.lat[ok], res.h[ok]
    centre = (float(np.mean(lon)), float(np.mean(lat)))
    x, y = local_metres(lon, lat, centre)
    cols, rows = truth[1].size
    radius = precision.spread_radius(truth[1], cols / 2, rows / 2, 0.5 * (lo + hi))
    classes = gdal.Open(str(paths["classes"]))
    gt, values = classes.GetGeoTransform(), classes.ReadAsArray()
    distance = ndimage.distance_transform_edt(np.isin(values, list(OPEN))) * abs(gt[1]) * metres_per_lon(gt)
    i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, values.shape[0] - 1)
    j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, values.shape[1] - 1)
    return {
        "dh": h - dsm.height(lon, lat),
        "sh": res.sigma[ok, 2],
        "rays": res.rays[ok],
        "spread": local_spread(x, y, h, x, y, radius),
        "cls": values[i, j],
        "distance": distance[i, j],
        "radius": radius,
        "kept": (points["flags"][np.searchsorted(points["id"], res.point[ok])] & SEMI_GLOBAL) != 0,
    }


def metres_per_lon(gt):
    """Metres per degree of the class raster's columns (its geotransform is in degrees): 1 if projected."""
    return metres_per_degree(gt[3])[0] if abs(gt[1]) < 1.0 else 1.0


def sigma_h(e, calibration, factor):
    f = np.array([calibration.get(int(k), np.nan) for k in range(4)])[e["rays"]]
    return precision.with_spread(f * e["sh"], e["spread"], factor)


def fit(e):
    """(F_2, F_3, C) by non-negative least squares of dh^2 over the open classes."""
    m = np.isin(e["cls"], list(OPEN)) & np.isfinite(e["spread"])
    a = np.c_[
        np.where(e["rays"][m] == 2, e["sh"][m] ** 2, 0.0),
        np.where(e["rays"][m] == 3, e["sh"][m] ** 2, 0.0),
        e["spread"][m] ** 2,
    ]
    return np.sqrt(nnls(a, e["dh"][m] ** 2)[0])


def fit_semi_global(e, f2, f3, c):
    """The semi-global axis that calibrates the points with a position the bias test kept (all classes), given F_2, F_3
    and C: SEMI_GLOBAL_AXIS times the least-squares scale of their ray term."""
    m = e["kept"] & np.isfinite(e["spread"])
    rays = np.where(e["rays"][m] == 2, f2, f3) * e["sh"][m]
    scale = nnls(rays[:, None] ** 2, np.maximum(e["dh"][m] ** 2 - (c * e["spread"][m]) ** 2, 0.0))[0][0]
    return precision.SEMI_GLOBAL_AXIS * float(np.sqrt(scale))


def ratios(e, s, m):
    z = e["dh"][m] / s[m]
    return (
        f"{np.sqrt(np.mean(e['dh'][m] ** 2) / np.mean(s[m] ** 2)):.2f} / "
        f"{1.4826 * np.median(np.abs(z - np.median(z))):.2f}"
    )


def main():
    for label, config in SCENES.items():
        e = scene_errors(config)
        f2, f3, c = fit(e)
        product = sigma_h(e, precision.SPOT.factors, precision.SPOT.spread)
        raw = sigma_h(e, {2: 1.0, 3: 1.0}, 0.0)
        print(
            f"\n{label}: R {e['radius']:.1f} m; fitted here F_2 {f2:.2f}, F_3 {f3:.2f}, C {c:.2f}; the product's "
            f"F {precision.SPOT.factors}, C {precision.SPOT.spread}"
        )
        fitted = sigma_h(e, {2: f2, 3: f3}, c)
        print(
            "| rays, class | points (interior) | product: all; interior | fitted here: all; interior | F = 1, no "
            "spread: all; interior |\n|---|---|---|---|---|"
        )
        for rays in (2, 3):
            for k, name in OPEN.items():
                m = (e["cls"] == k) & (e["rays"] == rays)
                inner = m & (e["distance"] >= INTERIOR)
                print(
                    f"| {rays}, {name} | {m.sum()} ({inner.sum()}) | {ratios(e, product, m)}; "
                    f"{ratios(e, product, inner)} | {ratios(e, fitted, m)}; {ratios(e, fitted, inner)} | "
                    f"{ratios(e, raw, m)}; {ratios(e, raw, inner)} |"
                )
        print(
            f"points with a semi-global position the bias test kept: {e['kept'].sum()}; the axis that calibrates them "
            f"(F and C fitted here): {fit_semi_global(e, f2, f3, c):.2f} px (the product's "
            f"{precision.SEMI_GLOBAL_AXIS});"
            " the product's RMS(dh) / RMS(sigma_h) / NMAD(dh / sigma_h) by class: "
            + ", ".join(
                f"{name} {ratios(e, product, e['kept'] & (e['cls'] == k))} ({(e['kept'] & (e['cls'] == k)).sum()})"
                for k, name in CLASS_NAMES.items()
                if (e["kept"] & (e["cls"] == k)).sum() >= 20
            )
        )


if __name__ == "__main__":
    main()
