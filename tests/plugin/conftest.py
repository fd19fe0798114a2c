"""Fixtures of the Processing algorithm tests: a recording feedback, and a private QGIS profile for
running qgis_process as a user would (the provider fixture is in tests/conftest.py)."""

import json
import subprocess

import pytest
from qgis.core import QgsProcessingFeedback

from tests.helpers.qgis_process_profile import QGIS_PROCESS, qgis_process_env


class RecordingFeedback(QgsProcessingFeedback):
    """QgsProcessingFeedback that also keeps the info, warning and error messages it is given."""

    def __init__(self):
        super().__init__()
        self.messages, self.warnings, self.errors = [], [], []

    def reportError(self, error, fatalError=False):
        self.errors.append(error)
        super().reportError(error, fatalError)

    def pushInfo(self, text):
        self.messages.append(text)
        super().pushInfo(text)

    def pushWarning(self, text):
        self.warnings.append(text)
        super().pushWarning(text)


@pytest.fixture
def log():
    """A fresh RecordingFeedback (.messages, .warnings, .errors)."""
    return RecordingFeedback()


@pytest.fixture(scope="session")
def qgis_process(tmp_path_factory):
    """Run `qgis_process.bin ARGS --json` with a profile that has the plugin enabled; returns the
    parsed JSON (raises with the output on failure)."""
    env = qgis_process_env(tmp_path_factory.mktemp("qgis-profile"))

    def run(*args):
        proc = subprocess.run([QGIS_PROCESS, "--json", *args], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(
                f"qgis_process {' '.join(args)} failed ({proc.returncode}):\n"
                f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
            )
        return json.loads(proc.stdout[proc.stdout.index("{") :])

    return run
