"""A scripted user session inside the real QGIS desktop (`qgis.bin --code THIS_FILE`, run by
tests/ui/test_qgis_desktop.py): once the event loop runs, find the "Measure control points..." action, open
the measurement window for the block of the active layer through it, measure the job's points (ground from
lon/lat/h, a click at the true position in the first image, the LSM transfers accepted, a click at the truth in
any image the transfer missed), write what happened to the job's result file and quit QGIS. A watchdog names
any dialog still open after WATCHDOG_MS (a modal one would block QGIS) and ends the process.

The job is the JSON file named by the environment variable PUSHBROOM_SESSION: {"block": path, "result": path,
"points": [{"name", "lon", "lat", "h", "image": {image id (str): [col, row]}}]}."""

import json
import os
import sys
import traceback

import qgis.utils
from qgis.core import QgsProject, QgsVectorLayer
from qgis.PyQt.QtCore import QTimer
from qgis.PyQt.QtWidgets import QAction, QApplication, QMessageBox, QToolBar

from tests.helpers.desktop_exit import run_then_quit

JOB = json.load(open(os.environ["PUSHBROOM_SESSION"], encoding="utf-8"))
RESULT = {"errors": [], "transfer_notes": {}}
WATCHDOG_MS = 120000


def write_result():
    with open(JOB["result"], "w", encoding="utf-8") as f:
        json.dump(RESULT, f, indent=1)


def record_exception(kind, value, tb):
    """Exceptions in Qt slots (the action's) go to the result instead of a QGIS error dialog."""
    RESULT["errors"].append("".join(traceback.format_exception(kind, value, tb)))


def control_layers():
    """[name, feature count, renderer type] of the project's layers of the block's control points."""
    from pushbroom.plugin.control_layer import find_control_layer

    layer = find_control_layer(JOB["block"])
    return [] if layer is None else [[layer.name(), layer.featureCount(), layer.renderer().type()]]


def measure(window, point):
    """Measure one point through the window's scripting methods; returns the image ids measured by transfer
    (why the others failed goes to the result's transfer_notes)."""
    images = {int(k): v for k, v in point["image"].items()}
    first = min(images)
    window.new_point(point["name"], role="control")
    window.set_ground(point["lon"], point["lat"], crs="EPSG:4326", h=point["h"])
    window.click_image(first, *images[first])
    RESULT["transfer_notes"][point["name"]] = dict(window.session.transfer_notes)
    window.accept_pending()
    obs = window.session.observations
    index = list(obs.points["name"]).index(point["name"])
    measured = {int(m["image_id"]) for m in obs.measurements if m["point"] == index}
    for image_id in sorted(set(images) - measured):
        window.click_image(image_id, *images[image_id], transfer=False)
    return sorted(measured - {first})


def session():
    iface = qgis.utils.iface
    main = iface.mainWindow()
    action = main.findChild(QAction, "pushbroom_measure")
    RESULT["action"] = action is not None
    RESULT["toolbars"] = [
        t.windowTitle() for t in main.findChildren(QToolBar) if action in t.actions() and t.isVisible()
    ]
    footprints = QgsVectorLayer(f"{JOB['block']}|layername=footprints", "footprints", "ogr")
    QgsProject.instance().addMapLayer(footprints)
    iface.setActiveLayer(footprints)
    action.trigger()
    windows = [w for w in QApplication.topLevelWidgets() if type(w).__name__ == "MeasurementWindow" and w.isVisible()]
    RESULT["windows"] = len(windows)
    RESULT["layers_on_open"] = control_layers()
    window = windows[0]
    RESULT["transferred"] = {p["name"]: measure(window, p) for p in JOB["points"]}
    action.trigger()  # a second trigger shows the same window
    RESULT["windows_after_second_trigger"] = len(
        [w for w in QApplication.topLevelWidgets() if type(w).__name__ == "MeasurementWindow"]
    )
    from pushbroom.plugin.control_layer import show_control_points

    show_control_points(JOB["block"])
    RESULT["layers_at_end"] = control_layers()
    window.close()


def run_and_quit():
    run_then_quit(session, RESULT, write_result)


def watchdog():
    """Runs inside a modal dialog's event loop too: name the open dialogs and end QGIS."""
    dialogs = [
        f"{type(w).__name__} {w.windowTitle()!r}" + (f": {w.text()}" if isinstance(w, QMessageBox) else "")
        for w in QApplication.topLevelWidgets()
        if w.isVisible() and w is not qgis.utils.iface.mainWindow()
    ]
    RESULT["errors"].append(f"QGIS still running after {WATCHDOG_MS} ms; open windows: {dialogs}")
    write_result()
    os._exit(3)


sys.excepthook = record_exception
QTimer.singleShot(0, run_and_quit)
QTimer.singleShot(WATCHDOG_MS, watchdog)
