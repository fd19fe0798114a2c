"""Progress reporting and cancelling without QGIS: any object with the methods of
QgsProcessingFeedback (setProgress, isCanceled, pushInfo) can be passed as `feedback`."""
from .errors import CancelledError


class NullFeedback:
    """Feedback that reports nothing and never cancels."""

    def setProgress(self, percent):
        pass

    def isCanceled(self):
        return False

    def pushInfo(self, text):
        pass


def ensure(feedback):
    """Return `feedback`, or a NullFeedback when None."""
    return NullFeedback() if feedback is None else feedback


def step(feedback, percent, message=None):
    """Report `percent` (0-100) and an optional message; raise CancelledError if cancelled."""
    if feedback is None:
        return
    if feedback.isCanceled():
        raise CancelledError("cancelled by the user")
    feedback.setProgress(float(percent))
    if message:
        feedback.pushInfo(message)
