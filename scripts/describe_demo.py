"""Print what `make demo` made: the simulated images with the measured error of their supplied
and of their adjusted orientation (the block's models) against the truth, the stereo geometry,
the files, the mass points per group, the accuracy of the group-3 image points against the truth
per land-cover class, and from the log of the pipeline model (pipeline.log): the bundle
adjustment's tables (Kornus et al. 2006, Tables 2-4, check points) and the accuracy of the object points per point
group and of the DEM against the true DSM (pushbroom:assessaccuracy)."""

import csv
import json
import os
import sys

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.geodesy import metres_per_degree

#: land-cover classes of the simulator (classes.tif) grouped as in the report
CLASS_GROUPS = {"fields (bare, crops)": (2, 3), "forest": (4,), "city": (5,), "water": (1,)}


def orientation_error_m(supplied, truth, h):
    """RMS and max ground distance (m) between a model and the true model on a 9 x 9 grid."""
    cols, rows = supplied.size
    c, r = (v.ravel() for v in np.meshgrid(np.linspace(0, cols, 9), np.linspace(0, rows, 9)))
    lon1, lat1 = supplied.image_to_ground(c, r, h)
    lon2, lat2 = truth.image_to_ground(c, r, h)
    me, mn = metres_per_degree(float(np.mean(lat1)))
    d = np.hypot((lon1 - lon2) * me, (lat1 - lat2) * mn)
    return float(np.sqrt(np.mean(d * d))), float(d.max())


def group3_accuracy(out, step=10.0, margin=20.0):
    """Rows (class, N, RMS and share > 1 px in each forward/backward image, coverage) of the group-3
    points: the truth position of a point in HRS1/HRS2 is the truth HRG ray of its HRG observation
    intersected with the true DSM and projected with the truth HRS1/HRS2 model; coverage is the
    share of STEP-spaced HRG lattice nodes (inside `margin` px) holding a group-3 point."""
    scene = os.path.join(out, "scene")
    blk = Block(os.path.join(out, "block.gpkg"))
    ids = {r["name"]: r["id"] for r in blk.images()}
    truth = {name: sensors.load(os.path.join(scene, "truth", name, "METADATA.DIM")) for name in ids}
    dsm = read_dem(os.path.join(scene, "dsm.tif"))
    ds = gdal.Open(os.path.join(scene, "classes.tif"))
    classes, gt = ds.ReadAsArray(), ds.GetGeoTransform()

    def class_at(lon, lat):
        i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, classes.shape[0] - 1)
        j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, classes.shape[1] - 1)
        return classes[i, j]

    mass = blk.points("mass_points")
    g3 = mass.points["id"][mass.points["group"] == 3]

    def observed(name):
        o = mass.observations[mass.observations["image_id"] == ids[name]]
        o = o[np.argsort(o["point_id"], kind="stable")]
        k = np.clip(np.searchsorted(o["point_id"], g3), 0, len(o) - 1)
        return o["col"][k], o["row"][k], o["point_id"][k] == g3

    c0, r0, ok0 = observed("HRG")
    lon, lat, h = truth["HRG"].image_to_dem(c0, r0, dsm)
    cls = class_at(lon, lat)
    errors = {}
    for name in ("HRS1", "HRS2"):
        c, r, ok = observed(name)
        x, y = truth[name].ground_to_image(lon, lat, h)
        e = np.hypot(x - c, y - r)
        errors[name] = (e, ok & ok0 & np.isfinite(e))
    cols, rows = truth["HRG"].size
    nx, ny = np.arange(margin, cols - margin + 1e-9, step), np.arange(margin, rows - margin + 1e-9, step)
    gx, gy = (v.ravel() for v in np.meshgrid(nx, ny))
    node_cls = class_at(*truth["HRG"].image_to_dem(gx, gy, dsm)[:2])
    occupied = np.zeros((ny.size, nx.size), bool)
    j, i = np.round((c0[ok0] - margin) / step).astype(int), np.round((r0[ok0] - margin) / step).astype(int)
    inside = (j >= 0) & (j < nx.size) & (i >= 0) & (i < ny.size)
    occupied[i[inside], j[inside]] = True
    occupied = occupied.ravel()
    table = []
    for label, codes in CLASS_GROUPS.items():
        row = [label]
        for name in ("HRS1", "HRS2"):
            e, valid = errors[name]
            sel = valid & np.isin(cls, codes)
            row += [
                int(sel.sum()),
                float(np.sqrt(np.mean(e[sel] ** 2))) if sel.any() else float("nan"),
                100.0 * float(np.mean(e[sel] > 1.0)) if sel.any() else float("nan"),
            ]
        nodes = np.isin(node_cls, codes)
        row.append(100.0 * float(occupied[nodes].mean()) if nodes.any() else float("nan"))
        table.append(row)
    return table


#: titles of the log sections printed: the adjustment's, then the assessment's (algorithms/quality/report.py)
ADJUSTMENT_SECTIONS = (
    "Adjustment",
    "Free orientation parameters",
    "Check points (Kornus et al. 2006, Table 3)",
    "Tie point heights against the reference",
)
ACCURACY_SECTIONS = ("of the object points - reference: per point group", "of the DEM cells")


def report_tables(log, keys):
    """The sections of a Processing log (adjustment/report.render_text: a title line ending in ':',
    indented lines, a blank line) whose title holds one of `keys`."""
    sections, current = [], None
    for line in open(log).read().splitlines():
        if line and not line.startswith(" ") and line.endswith(":"):
            current = [line] if any(k in line for k in keys) else None
            if current:
                sections.append(current)
        elif current is not None and line.startswith("  "):
            current.append(line)
        else:
            current = None
    return sections


def main(out):
    scene = os.path.join(out, "scene")
    truth = json.load(open(os.path.join(scene, "truth", "truth.json")))
    with open(os.path.join(scene, "points.csv")) as f:
        points = list(csv.DictReader(f))
    h = float(np.mean([float(p["h"]) for p in points])) if points else 0.0
    blk = os.path.join(out, "block.gpkg")
    print(f"\nDemo output in {out}")
    print(
        f"{'image':6} {'cols x rows':>13}  orientation vs truth on the ground (h = {h:.0f} m): supplied, "
        "block (after the adjustment)"
    )
    for row in Block(blk).images():
        exact = sensors.load(os.path.join(scene, "truth", row["name"], "METADATA.DIM"))
        errors = [
            orientation_error_m(model, exact, h)
            for model in (sensors.load(os.path.join(scene, row["name"], "METADATA.DIM")), Block(blk).model(row["id"]))
        ]
        print(
            f"{row['name']:6} {row['cols']:>6} x {row['rows']:<6} "
            + "; ".join(f"RMS {rms:5.1f} m, max {worst:5.1f} m" for rms, worst in errors)
        )
    print("base-to-height ratios: " + ", ".join(f"{k} {v:.2f}" for k, v in truth["base_to_height"].items()))
    print(f"{len(points)} control/check point candidates in points.csv")
    for name in ("dsm.tif", "dtm.tif", "classes.tif", "orthoimage.tif", "points.csv", "truth/truth.json"):
        print(f"  {os.path.join(scene, name)}")
    print(f"  {blk} (images, sensor models, footprints, mass and tie point layers, control/check points)")
    for name, what in (
        ("pipeline.log", "log of the pipeline model run (qgis_process)"),
        ("adjustment.html", "bundle adjustment report"),
        ("residuals.gpkg", "residual vectors of the control and check points"),
        ("points.las", "mass points intersected with the adjusted models"),
        ("dem.tif", "DEM interpolated from the point cloud"),
        ("orthoimage_HRG.tif", "orthoimage of HRG on the adjusted model and the DEM"),
        ("report.html", "accuracy of the point cloud and the DEM against the true DSM"),
        ("accuracy.csv", "the accuracy statistics as a table"),
        ("dh.tif", "dh of the DEM against the true DSM"),
        ("pushbroom_demo.qgz", "QGIS project with all layers styled"),
    ):
        if os.path.exists(os.path.join(out, name)):
            print(f"  {os.path.join(out, name)} ({what})")
    table = os.path.join(out, "point_groups.csv")
    if os.path.exists(table):
        with open(table) as f:
            rows = list(csv.reader(f))[1:]
        width = max(len(label) for label, _ in rows)
        print("\nMass points per group (as Table 1 of Kornus et al. 2006):")
        for label, value in rows:
            print(f"  {label:<{width}}  {value:>10}")
        print("\nGroup-3 points against the truth (truth HRG ray on the true DSM, projected with the truth models):")
        print(
            f"  {'class':22} {'N':>7} {'HRS1 RMS px':>12} {'> 1 px':>7} {'HRS2 RMS px':>12} {'> 1 px':>7} "
            f"{'coverage':>9}"
        )
        for label, n1, rms1, big1, _, rms2, big2, cover in group3_accuracy(out):
            print(f"  {label:22} {n1:>7} {rms1:>12.3f} {big1:>6.2f}% {rms2:>12.3f} {big2:>6.2f}% {cover:>8.1f}%")
    log = os.path.join(out, "pipeline.log")
    if os.path.exists(log):
        print(
            "\nBundle adjustment (automatic parameter selection; check points: simulated reference coordinates; "
            "tie point heights: the true DSM):"
        )
        for section in report_tables(log, ADJUSTMENT_SECTIONS):
            print("\n" + "\n".join(section))
        print("\nAccuracy of the point cloud and the DEM against the true DSM (pushbroom:assessaccuracy; report.html):")
        for section in report_tables(log, ACCURACY_SECTIONS):
            print("\n" + "\n".join(section))


if __name__ == "__main__":
    main(sys.argv[1])
