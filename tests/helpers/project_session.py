"""A QGIS desktop session (`qgis.bin --code THIS_FILE` with the repository root on PYTHONPATH, run by
tests/ui/test_project_opens_clean.py, and by hand for the demo project): open the project named by
PUSHBROOM_PROJECT as a user would (File > Open), let it render, then write to the JSON file
PUSHBROOM_RESULT the message bar's items (QGIS shows a missing font, an unreadable layer or a bad style
there), the layers and whether they are valid, and a screenshot of the main window to
PUSHBROOM_SCREENSHOT; then quit."""

import json
import os
import traceback

import qgis.utils
from qgis.core import QgsProject
from qgis.PyQt.QtCore import QTimer

from tests.helpers.desktop_exit import run_then_quit

RESULT = {"errors": []}


def write():
    with open(os.environ["PUSHBROOM_RESULT"], "w", encoding="utf-8") as f:
        json.dump(RESULT, f, indent=1)


def inspect():
    iface = qgis.utils.iface
    RESULT["messages"] = [f"{item.title()}: {item.text()}" for item in iface.messageBar().items()]
    RESULT["layers"] = [[layer.name(), layer.isValid()] for layer in QgsProject.instance().mapLayers().values()]
    iface.mainWindow().grab().save(os.environ["PUSHBROOM_SCREENSHOT"])


def open_project():
    try:
        qgis.utils.iface.addProject(os.environ["PUSHBROOM_PROJECT"])
        qgis.utils.iface.mainWindow().showMaximized()
        qgis.utils.iface.mapCanvas().zoomToFullExtent()
        qgis.utils.iface.mapCanvas().refreshAllLayers()
    except Exception:
        RESULT["errors"].append(traceback.format_exc())
    # the canvas renders and QGIS posts its messages meanwhile
    QTimer.singleShot(8000, lambda: run_then_quit(inspect, RESULT, write))


QTimer.singleShot(0, open_project)
QTimer.singleShot(120000, lambda: (RESULT["errors"].append("QGIS still running after 120 s"), write(), os._exit(3)))
