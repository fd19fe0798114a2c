"""Fixtures of the Processing algorithm tests: a recording feedback, and a private QGIS profile for
running qgis_process as a user would (the provider fixture is in tests/conftest.py)."""
import json
import os
import pathlib
import subprocess
import sys

import pytest
from qgis.core import QgsProcessingFeedback

import pushbroom

REPO = pathlib.Path(pushbroom.__file__).resolve().parent
QGIS_PROCESS = "/usr/bin/qgis_process.bin"


class RecordingFeedback(QgsProcessingFeedback):
    """QgsProcessingFeedback that also keeps the info and warning messages it is given."""

    def __init__(self):
        super().__init__()
        self.messages, self.warnings = [], []

    def pushInfo(self, text):
        self.messages.append(text)
        super().pushInfo(text)

    def pushWarning(self, text):
        self.warnings.append(text)
        super().pushWarning(text)


@pytest.fixture
def log():
    """A fresh RecordingFeedback (.messages, .warnings)."""
    return RecordingFeedback()


@pytest.fixture(scope="session")
def qgis_process(tmp_path_factory):
    """Run `qgis_process.bin ARGS --json` with a profile that has the plugin enabled; returns the
    parsed JSON (raises with the output on failure)."""
    profile = tmp_path_factory.mktemp("qgis-profile")
    plugins = profile / "profiles" / "default" / "python" / "plugins"
    plugins.mkdir(parents=True)
    (plugins / "pushbroom").symlink_to(REPO)
    site = [p for p in sys.path if p.endswith("site-packages") and ".venv" in p]
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", QGIS_CUSTOM_CONFIG_PATH=str(profile),
               PYTHONPATH=os.pathsep.join(site + [os.environ.get("PYTHONPATH", "")]))
    subprocess.run([QGIS_PROCESS, "plugins", "enable", "pushbroom"], env=env, capture_output=True)

    def run(*args):
        proc = subprocess.run([QGIS_PROCESS, "--json", *args], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"qgis_process {' '.join(args)} failed ({proc.returncode}):\n"
                               f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
        return json.loads(proc.stdout[proc.stdout.index("{"):])
    return run
