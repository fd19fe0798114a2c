"""Print what `make demo` made: the simulated images with the measured error of their supplied
orientation against the truth, the stereo geometry, the block and the mass points per group."""
import csv
import json
import math
import os
import sys

import numpy as np

from pushbroom.algorithms import block, sensors


def supplied_error_m(supplied, truth, h):
    """RMS and max ground distance (m) between the supplied and the true model on a 9 x 9 grid."""
    cols, rows = supplied.size
    c, r = (v.ravel() for v in np.meshgrid(np.linspace(0, cols, 9), np.linspace(0, rows, 9)))
    lon1, lat1 = supplied.image_to_ground(c, r, h)
    lon2, lat2 = truth.image_to_ground(c, r, h)
    d = np.hypot((lon1 - lon2) * 111_320 * math.cos(math.radians(lat1.mean())), (lat1 - lat2) * 110_574)
    return float(np.sqrt(np.mean(d * d))), float(d.max())


def main(out):
    scene = os.path.join(out, "scene")
    truth = json.load(open(os.path.join(scene, "truth", "truth.json")))
    with open(os.path.join(scene, "points.csv")) as f:
        points = list(csv.DictReader(f))
    h = float(np.mean([float(p["h"]) for p in points])) if points else 0.0
    blk = os.path.join(out, "block.gpkg")
    print(f"\nDemo output in {out}")
    print(f"{'image':6} {'cols x rows':>13}  supplied orientation vs truth on the ground (h = {h:.0f} m)")
    for row in block.read_images(blk):
        supplied = block.load_model(blk, row["id"])
        exact = sensors.load(os.path.join(scene, "truth", row["name"], "METADATA.DIM"))
        rms, worst = supplied_error_m(supplied, exact, h)
        print(f"{row['name']:6} {row['cols']:>6} x {row['rows']:<6} RMS {rms:5.1f} m, max {worst:5.1f} m")
    print("base-to-height ratios: " + ", ".join(f"{k} {v:.2f}" for k, v in truth["base_to_height"].items()))
    print(f"{len(points)} control/check point candidates in points.csv")
    for name in ("dsm.tif", "dtm.tif", "classes.tif", "orthoimage.tif", "points.csv", "truth/truth.json"):
        print(f"  {os.path.join(scene, name)}")
    print(f"  {blk} (images, sensor models, footprints, mass and tie point layers)")
    table = os.path.join(out, "point_groups.csv")
    if os.path.exists(table):
        with open(table) as f:
            rows = list(csv.reader(f))[1:]
        width = max(len(label) for label, _ in rows)
        print("\nMass points per group (as Table 1 of Kornus et al. 2006):")
        for label, value in rows:
            print(f"  {label:<{width}}  {value:>10}")


if __name__ == "__main__":
    main(sys.argv[1])
