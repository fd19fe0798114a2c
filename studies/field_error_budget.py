"""Where does region growing's error on fields come from (issue 3's 0.15 px target)? On the 3 km
simulated triplet (HRG -> HRS1, default GrowParams), with image noise 1 DN (the default) and 0, the
field points' error against the point truth split by their distance to forest, city or water
(templates that see height steps) into: the gap between the template-area truth and the point truth
(relief inside the template) and the matcher's error against the template-area truth; then the best
of LSM windows 9..19 px per point with the truth as the oracle."""

import pathlib
import tempfile

import numpy as np
from scipy import ndimage

from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing import match_pair, transfer_points
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from tests.helpers.matching_scene import SINGLE_SURFACE, Scene

NEAR_M = 50.0  # half an HRG template
WINDOWS = (9, 11, 13, 15, 19)


def rms(v):
    return float(np.sqrt(np.mean(np.square(v)))) if np.size(v) else float("nan")


def budget(paths, oracle):
    scene = Scene(paths)
    r = match_pair(ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams(), scene.height_range)
    tx, ty, cls = scene.truth(r["x1"], r["y1"])
    ax, ay = scene.area_truth(r)
    field = np.isin(cls, SINGLE_SURFACE)
    steps = ~np.isin(scene.classes, SINGLE_SURFACE)
    dist = ndimage.distance_transform_edt(~steps) * 5.0  # the 5 m ground grid
    lon, lat, _ = scene.truth1.image_to_dem(r["x1"], r["y1"], scene.dsm)
    near = dist[scene._cell(lon, lat)] < NEAR_M
    error = np.hypot(r["x2"] - tx, r["y2"] - ty)
    print(f"  fields: {field.sum()} points, RMS {rms(error[field]):.3f} px against the point truth")
    for label, k in ((f"within {NEAR_M:.0f} m of a height step", field & near), ("interior", field & ~near)):
        print(
            f"  {label:28} n {k.sum():5d} ({100 * k.sum() / field.sum():.0f} %): point RMS {rms(error[k]):.3f}; "
            f"area - point truth y {rms((ay - ty)[k]):.3f}; matcher - area truth x {rms((r['x2'] - ax)[k]):.3f} "
            f"y {rms((r['y2'] - ay)[k]):.3f} px"
        )
    if oracle:
        best = np.full(len(r), np.inf)
        for t in WINDOWS:
            rec, ok = transfer_points(
                ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
                r["x1"],
                r["y1"],
                GrowParams(template=t, max_ellipse=1.0),
                scene.height_range,
                guide=r,
            )
            e = np.hypot(rec["x2"] - tx, rec["y2"] - ty)
            best = np.fmin(best, np.where(ok & np.isfinite(e), e, np.inf))
        k = field & np.isfinite(best)
        print(f"  oracle: per point the best of windows {WINDOWS} px: fields RMS {rms(best[k]):.3f} px")


def main():
    with tempfile.TemporaryDirectory() as tmp:
        for noise in (1.0, 0.0):
            print(f"3 km triplet, image noise {noise:g} DN:")
            budget(simulate_scene(SceneConfig.small(noise=noise), pathlib.Path(tmp) / f"n{noise:g}"), noise > 0)


if __name__ == "__main__":
    main()
