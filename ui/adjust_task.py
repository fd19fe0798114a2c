"""'Adjust now' of the measurement window: pushbroom:bundleadjust on the block in a background
QgsTask (QgsProcessingAlgRunnerTask), so the GUI keeps responding.

The algorithm is taken from QGIS's Processing registry, where the Pushbroom provider registers it
when the plugin is loaded; without the provider the adjustment fails with a message saying so. The
engine's errors (InputError: too few control points, no points at all...) arrive as the algorithm's
reported error text, never as a traceback."""

import functools

from qgis.core import (
    QgsApplication,
    QgsProcessingAlgRunnerTask,
    QgsProcessingContext,
    QgsProcessingFeedback,
    QgsProject,
)
from qgis.PyQt.QtCore import QObject, QTimer, pyqtSignal

from ..algorithms.block import Block
from ..algorithms.errors import PushbroomError

ALGORITHM = "pushbroom:bundleadjust"
#: (task, context, feedback) of running adjustments by id(task): they outlive a window closed meanwhile
_RUNNING = {}


class ErrorFeedback(QgsProcessingFeedback):
    """Feedback that keeps the reported errors (`errors`): the algorithm's message on failure."""

    def __init__(self):
        super().__init__()
        self.errors = []

    def reportError(self, error, fatalError=False):
        self.errors.append(error)
        super().reportError(error, fatalError)


def bundle_adjust_algorithm():
    """The registered pushbroom:bundleadjust; PushbroomError when the Pushbroom provider is not loaded."""
    algorithm = QgsApplication.processingRegistry().algorithmById(ALGORITHM)
    if algorithm is None:
        raise PushbroomError(
            f"the Processing algorithm {ALGORITHM} is not registered: enable the Pushbroom "
            "plugin (Plugins > Manage and Install Plugins) so that its provider is loaded"
        )
    return algorithm


def parameters(block_path):
    """The algorithm's parameters for the block: automatic parameter selection, the block's tie points
    when it has some."""
    return {"BLOCK": str(block_path), "FREE": "auto", "USE_TIE_POINTS": "tie_points" in Block(block_path).info()}


class AdjustRunner(QObject):
    """Starts the adjustment task (`start`); emits finished(ok, message) in the GUI thread. The task,
    its context and feedback stay alive while it runs, also when the runner is deleted meanwhile."""

    finished = pyqtSignal(bool, str)
    progressChanged = pyqtSignal(float)

    def __init__(self, block_path, parent=None):
        super().__init__(parent)
        self.block_path = str(block_path)
        self.task = self.context = self.feedback = None

    def running(self):
        return self.task is not None

    def start(self):
        """Queue the adjustment in QGIS's task manager; False if one is already running. Without the
        registered algorithm, finished(False, why) is emitted once control returns to the event loop."""
        if self.running():
            return False
        try:
            algorithm = bundle_adjust_algorithm()
        except PushbroomError as exc:
            QTimer.singleShot(0, functools.partial(self.finished.emit, False, str(exc)))
            return True
        self.context = QgsProcessingContext()
        self.context.setProject(QgsProject.instance())
        self.feedback = ErrorFeedback()
        self.feedback.progressChanged.connect(self.progressChanged)
        self.task = QgsProcessingAlgRunnerTask(algorithm, parameters(self.block_path), self.context, self.feedback)
        self.task.executed.connect(self._executed)
        key = id(self.task)
        _RUNNING[key] = (self.task, self.context, self.feedback)
        release = functools.partial(_RUNNING.pop, key, None)
        self.task.taskCompleted.connect(release)
        self.task.taskTerminated.connect(release)
        QgsApplication.taskManager().addTask(self.task)
        return True

    def cancel(self):
        if self.task is not None:
            self.task.cancel()

    def _executed(self, ok, results):
        feedback = self.feedback
        self.task = self.context = self.feedback = None
        if ok:
            sigma0 = results.get("SIGMA0")
            self.finished.emit(True, "adjusted" + (f": sigma_0 {sigma0:.3f}" if sigma0 is not None else ""))
        elif feedback.isCanceled():
            self.finished.emit(False, "adjustment cancelled")
        else:
            self.finished.emit(False, feedback.errors[-1] if feedback.errors else "the adjustment failed")
