"""Nothing is lost when the measurement window's process is killed: a session in a subprocess
(tests/helpers/measurement_crash_session.py) edits a block and SIGKILLs itself before closing; the block, read
again, holds exactly what the window showed, and a new window opens it with those points."""

import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys

from pushbroom.algorithms.block import Block
from pushbroom.ui.measurement_window import MeasurementWindow

SESSION = pathlib.Path(__file__).parents[1] / "helpers" / "measurement_crash_session.py"


def test_killed_session_loses_nothing(qtbot, marked_block, marked_scene, tmp_path):
    path = tmp_path / "block.gpkg"
    shutil.copy(marked_block, path)
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    result = tmp_path / "shown.json"
    proc = subprocess.run(
        [sys.executable, str(SESSION), str(path), marked_scene["dsm"], marked_scene["points"], str(result)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == -signal.SIGKILL, proc.stderr[-3000:]
    shown = json.loads(result.read_text())
    assert sorted(shown["points"]) == ["K1", "K3"] and shown["points"]["K1"][0] == "check"
    assert [m[0] for m in shown["measurements"]] == ["K1"] * 3
    assert not os.path.exists(f"{path}-journal")  # no transaction was open at the kill

    obs = Block(path).measurement_store().load()
    stored = {str(p["name"]): [p[k].item() for k in ("role", "lon", "lat", "h", "sigma_e")] for p in obs.points}
    assert stored == shown["points"]
    meas = sorted(
        [str(obs.points["name"][m["point"]]), int(m["image_id"]), float(m["col"]), float(m["row"])]
        for m in obs.measurements
    )
    assert meas == shown["measurements"]

    window = MeasurementWindow(str(path), reference_layers=[], dem_path=marked_scene["dsm"])
    qtbot.addWidget(window)
    try:
        window.show()
        assert sorted(window.table.names()) == ["K1", "K3"]
        window.select_point("K1")
        assert window.session.current == "K1" and window.editor.role.currentText() == "check"
        for view in window.image_views.values():
            selected = [m for m in view._markers if m.kind == "selected"]
            assert len(selected) == 1 and selected[0].label == "K1"
    finally:
        for view in window.image_views.values():
            view.clear()
