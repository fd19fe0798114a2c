"""A measurement window session that is killed (SIGKILL) before it closes, run as its own process by
test_measurement_window_crash.py.

measurement_crash_session.py BLOCK DEM POINTS_CSV RESULT_JSON: opens the window (offscreen), makes edits through
its scripting methods (two points set on the reference and measured, one with LSM transfers accepted,
a third created, deleted and restored by undo, the second deleted, the first made a check point),
writes the state the window shows to RESULT_JSON and kills itself without closing anything."""

import csv
import json
import os
import signal
import sys


def main(block_path, dem_path, points_csv, result_path):
    from qgis.core import QgsApplication

    app = QgsApplication([], True)
    app.initQgis()
    from pushbroom.algorithms.atomic import write_text
    from pushbroom.ui.measurement_window import MeasurementWindow

    with open(points_csv, newline="") as f:
        truth = {r["id"]: {k: float(v) for k, v in r.items() if k != "id"} for r in csv.DictReader(f)}
    window = MeasurementWindow(block_path, reference_layers=[], dem_path=dem_path)
    window.show()
    app.processEvents()
    ids = {name: i for i, name in window.session.image_names.items()}
    for name, point in (("K1", "P001"), ("K2", "P002"), ("K3", "P003")):
        p = truth[point]
        window.new_point(name)
        window.set_ground(p["lon"], p["lat"], crs="EPSG:4326")
        if name == "K1":
            window.click_image(ids["HRG"], p["HRG_col"], p["HRG_row"])
            window.accept_pending()
        elif name == "K2":
            window.click_image(ids["HRS1"], p["HRS1_col"], p["HRS1_row"], transfer=False)
            window.click_image(ids["HRG"], p["HRG_col"], p["HRG_row"], transfer=False)
    window.delete_point("K3")
    window.undo_stack.undo()
    window.delete_point("K2")
    window.edit_point("K1", role="check", sigma_e=1.25)
    app.processEvents()
    obs = window.session.observations
    state = {
        "points": {str(p["name"]): [p[k].item() for k in ("role", "lon", "lat", "h", "sigma_e")] for p in obs.points},
        "measurements": sorted(
            [str(obs.points["name"][m["point"]]), int(m["image_id"]), float(m["col"]), float(m["row"])]
            for m in obs.measurements
        ),
        "undo_steps": window.undo_stack.count(),
    }
    write_text(result_path, json.dumps(state))
    os.kill(os.getpid(), signal.SIGKILL)


if __name__ == "__main__":
    main(*sys.argv[1:5])
