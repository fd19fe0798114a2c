"""The end of a scripted QGIS desktop session (the `--code` scripts in this folder, which find this module
through PYTHONPATH): run the session's step, keep its traceback, write its result, and quit QGIS without a
question (no project to save, no layers in a temporary folder to keep)."""

import traceback

import qgis.utils
from qgis.core import QgsProject


def run_then_quit(step, result, write):
    """step(); a failure goes to result["errors"]; then write() and quit."""
    try:
        step()
    except Exception:  # everything goes to the test's log
        result["errors"].append(traceback.format_exc())
    write()
    QgsProject.instance().clear()
    QgsProject.instance().setDirty(False)
    qgis.utils.iface.actionExit().trigger()
