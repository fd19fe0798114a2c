"""Desktop check of a coloured point cloud (issue 40): run in desktop QGIS by `qgis --code`, it runs
pushbroom:intersectpoints on a block with the EPT output through Processing, as a user would, and saves screenshots
of the main window and the map canvas (widget.grab()) once the cloud Processing loaded is drawn; then it quits.

    make package
    mkdir -p DIR/profiles/default/python/plugins && unzip -q dist/pushbroom-*.zip -d DIR/profiles/default/python/plugins
    printf '[PythonPlugins]\\npushbroom=true\\n' > DIR/profiles/default/QGIS/QGIS3.ini
    BLOCK=block.gpkg OUT=folder PYTHONPATH=$(ls -d .venv/lib/python3*/site-packages) \\
        xvfb-run -a -s "-screen 0 1600x1000x24" qgis --profiles-path DIR --nologo --code scripts/desktop_point_cloud.py

OUT receives desk.laz, desk.ept/, main.png, canvas.png and layers.txt (each loaded layer: name, class, valid, points,
renderer)."""

import os

import processing
from qgis.core import QgsPointCloudLayer, QgsProject
from qgis.PyQt.QtCore import QTimer
from qgis.utils import iface

BLOCK, OUT = os.environ["BLOCK"], os.environ["OUT"]
#: ms to let QGIS start, and to let the canvas draw the cloud
START, DRAW = 5000, 20000


def run():
    try:
        processing.runAndLoadResults(
            "pushbroom:intersectpoints",
            {"BLOCK": BLOCK, "POINTS": 0, "OUTPUT": f"{OUT}/desk.laz", "EPT": f"{OUT}/desk.ept"},
        )
        layers = list(QgsProject.instance().mapLayers().values())
        with open(f"{OUT}/layers.txt", "w", encoding="utf-8") as f:
            for layer in layers:
                points = layer.pointCount() if isinstance(layer, QgsPointCloudLayer) else ""
                renderer = layer.renderer().type() if isinstance(layer, QgsPointCloudLayer) else ""
                f.write(f"{layer.name()}\t{type(layer).__name__}\t{layer.isValid()}\t{points}\t{renderer}\n")
        cloud = next(layer for layer in layers if isinstance(layer, QgsPointCloudLayer))
        iface.mapCanvas().setExtent(cloud.extent())
        iface.mapCanvas().refresh()
    except Exception as exc:  # written down for the one who runs the check
        with open(f"{OUT}/layers.txt", "a", encoding="utf-8") as f:
            f.write(f"ERROR {exc!r}\n")
    QTimer.singleShot(DRAW, shot)


def shot():
    iface.mainWindow().grab().save(f"{OUT}/main.png")
    iface.mapCanvas().grab().save(f"{OUT}/canvas.png")
    QTimer.singleShot(500, lambda: os._exit(0))


QTimer.singleShot(START, run)
