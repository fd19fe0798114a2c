"""How honest would the dense points' precision be if each image position carried LSM's error ellipse? On the
3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the DSM's height range +- 100 m), dense matching with the
default DenseParams but 256 px tiles, the points whose every image-2 position LSM refined, intersected with
the TRUE models (so the error is the matching's alone) with each matched image's sigma = K x its ellipse's
semi-major axis / sqrt(2) and the reference image's the smallest of those (the pair's relative error shared
between its two rays), for K = 1 ... 4: per class and per number of rays, the NMAD of dh / sigma_h and
RMS(dh) / RMS(sigma_h) (1 is calibrated) against the true DSM."""
import tempfile

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.block_tiles import match_dense_tiles
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.surface import intersection
from studies.dense_fusion import NAMES, class_at

SCALES = (1.0, 2.0, 3.0, 4.0)
OPEN = {2: "bare", 3: "crops"}


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    truth = {k: sensors.load(paths["truth_metadata"][n]) for k, n in enumerate(NAMES, start=1)}
    dsm = read_dem(paths["dsm"])
    lo, hi = dsm.height_range
    parts, _ = match_dense_tiles(images, models, tempfile.mkdtemp() + "/dense", params=DenseParams(tile=256),
                                 height_range=(lo - 100.0, hi + 100.0), execution=Execution("threads", 2))
    obs = np.concatenate([p.observations for p in parts])
    unrefined = np.unique(obs["point_id"][~np.isfinite(obs["semi_major"]) & (obs["image_id"] != 1)])
    obs = obs[~np.isin(obs["point_id"], unrefined)]
    classes = gdal.Open(str(paths["classes"]))
    _, inverse = np.unique(obs["point_id"], return_inverse=True)
    matched = obs["image_id"] != 1
    for scale in SCALES:
        relative = np.where(matched, scale * obs["semi_major"], np.inf)
        smallest = np.full(inverse.max() + 1, np.inf)
        np.minimum.at(smallest, inverse, relative)
        sigma = np.where(matched, relative, smallest[inverse]) / np.sqrt(2.0)
        res = intersection.intersect(truth, obs["image_id"], obs["point_id"], obs["col"], obs["row"], sigma=sigma,
                                     h0=0.5 * (lo + hi))
        ok = res.ok
        dh = res.h[ok] - dsm.height(res.lon[ok], res.lat[ok])
        sh = res.sigma[ok, 2]
        cls = class_at(classes, res.lon[ok], res.lat[ok])
        line = [f"K {scale:g}"]
        for k, name in OPEN.items():
            for rays in (2, 3):
                m = (cls == k) & (res.rays[ok] == rays)
                z = dh[m] / sh[m]
                nmad = 1.4826 * np.median(np.abs(z - np.median(z)))
                line.append(f"{name} {rays} rays ({m.sum()}): NMAD(dh/s) {nmad:.2f}, RMS ratio "
                            f"{np.sqrt(np.mean(dh[m] ** 2) / np.mean(sh[m] ** 2)):.2f}")
        print(" | ".join(line))


if __name__ == "__main__":
    main()
