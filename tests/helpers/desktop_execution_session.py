"""A scripted session inside the real QGIS desktop (`qgis.bin --code THIS_FILE`, run by
tests/ui/test_qgis_desktop.py): once the event loop runs, pushbroom:interpolatedem through Processing with
each execution of the job, while a thread records the executables of the processes QGIS starts (the
workers); then the result file is written and QGIS quits.

The job is the JSON file named by the environment variable PUSHBROOM_SESSION: {"cloud": path, "result":
path, "runs": {execution name: [execution index, output path]}}. The result: {"errors": [...],
"host": sys.executable, "workers": {execution name: [executables]}, "outputs": {execution name: path}}."""

import json
import os
import sys
import threading
import time

from qgis import processing
from qgis.core import QgsProcessingFeedback
from qgis.PyQt.QtCore import QTimer

from tests.helpers.desktop_exit import run_then_quit
from tests.helpers.processes import descendants

JOB = json.load(open(os.environ["PUSHBROOM_SESSION"], encoding="utf-8"))
RESULT = {"errors": [], "host": sys.executable, "workers": {}, "outputs": {}}


def write_result():
    with open(JOB["result"], "w", encoding="utf-8") as f:
        json.dump(RESULT, f, indent=1)


def watch(found, stop):
    """Add the executables of this process's descendants to `found` until `stop` is set."""
    while not stop.is_set():
        for pid in descendants(os.getpid()):
            try:
                found.add(os.readlink(f"/proc/{pid}/exe"))
            except OSError:
                pass
        time.sleep(0.01)


def session():
    for name, (execution, output) in JOB["runs"].items():
        found, stop = set(), threading.Event()
        watcher = threading.Thread(target=watch, args=(found, stop))
        watcher.start()
        try:
            result = processing.run(
                "pushbroom:interpolatedem",
                {
                    "INPUT": JOB["cloud"],
                    "CELL": 10.0,
                    "TILE": 75,
                    "EXECUTION": execution,
                    "WORKERS": 2,
                    "OUTPUT": output,
                },
                feedback=QgsProcessingFeedback(),
            )
        finally:
            stop.set()
            watcher.join()
        RESULT["workers"][name] = sorted(found)
        RESULT["outputs"][name] = result["OUTPUT"]


QTimer.singleShot(0, lambda: run_then_quit(session, RESULT, write_result))
