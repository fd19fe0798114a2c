"""The execution parameters of the tiled steps (plugin/algorithms/base.py: execution_parameters and
execution_choice): a malformed scheduler address refused before any work, and a cancel that the Qt event
loop delivers (qgis_process's Ctrl+C) reaching the running tiles."""

import os

import pytest
from qgis import processing
from qgis.core import QgsApplication, QgsProcessingContext, QgsProcessingException, QgsProcessingFeedback
from qgis.PyQt.QtCore import QTimer

from pushbroom.algorithms.errors import CancelledError
from pushbroom.algorithms.execution import run_tasks
from pushbroom.plugin.algorithms.base import execution_choice
from tests.helpers import execution_tasks as tasks


def test_a_malformed_scheduler_address_is_refused_before_any_work(pushbroom_provider, small_scene_block, tmp_path):
    block = tmp_path / "block.gpkg"
    block.write_bytes(small_scene_block[0].read_bytes())
    message = None
    try:  # the block has no points: the address is refused first, before anything is read
        processing.run(
            "pushbroom:intersectpoints",
            {
                "BLOCK": str(block),
                "EXECUTION": 2,
                "DASK_ADDRESS": " htp:/nonsense::99 ",
                "OUTPUT": str(tmp_path / "points.gpkg"),
            },
            context=QgsProcessingContext(),
        )
    except QgsProcessingException as exc:  # only the text is kept (no traceback holding QGIS objects)
        message = str(exc)
    assert message is not None and "'htp:/nonsense::99'" in message and "tcp://host:port" in message
    assert os.listdir(tmp_path) == ["block.gpkg"]  # nothing written


def test_a_cancel_from_the_qt_event_loop_reaches_the_running_tiles(pushbroom_provider, tmp_path):
    # qgis_process cancels the feedback on Ctrl+C from its Qt event loop, which runs while the tiles run only
    # through execution_choice's host_events (the algorithm runs on the main thread there, as here)
    algorithm = QgsApplication.processingRegistry().algorithmById("pushbroom:intersectpoints")
    where = execution_choice(algorithm, {"EXECUTION": 0, "WORKERS": 2}, QgsProcessingContext())
    feedback = QgsProcessingFeedback()
    QTimer.singleShot(300, feedback.cancel)  # a Qt event, as Ctrl+C's
    with pytest.raises(CancelledError):
        run_tasks(tasks.staged, [(str(tmp_path), k, 100, 0.05) for k in range(2)], where, feedback)
    stages = [n for n in os.listdir(tmp_path) if not n.startswith("pid-")]
    # both tasks stopped at a look at the token, soon after the 0.3 s (6 stages): far from their 100 stages
    assert 0 < len(stages) < 2 * 50, sorted(stages)


@pytest.mark.parametrize("given, wait", [({}, 60.0), ({"DASK_WAIT": 7.5}, 7.5), ({"DASK_WAIT": None}, 60.0)])
def test_the_wait_for_a_dask_worker_is_a_parameter_with_a_default(pushbroom_provider, given, wait):
    algorithm = QgsApplication.processingRegistry().algorithmById("pushbroom:interpolatedem")
    where = execution_choice(
        algorithm, {"EXECUTION": 2, "DASK_ADDRESS": "tcp://10.0.0.5:8786", **given}, QgsProcessingContext()
    )
    assert (where.backend, where.address, where.worker_wait) == ("dask", "tcp://10.0.0.5:8786", wait)
