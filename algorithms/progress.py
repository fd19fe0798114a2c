"""Progress reporting and cancelling without QGIS: any object with the methods of
QgsProcessingFeedback (setProgress, isCanceled, pushInfo; pushWarning where it has it) can be
passed as `feedback`."""

from typing import Protocol

from .errors import CancelledError


class Feedback(Protocol):
    """What the engine calls on a feedback: QgsProcessingFeedback's methods of that name."""

    def setProgress(self, percent: float) -> None: ...

    def isCanceled(self) -> bool: ...

    def pushInfo(self, text: str) -> None: ...


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


def check(feedback):
    """Raise CancelledError if `feedback` (or None) is cancelled; the progress stays where it is."""
    if feedback is not None and feedback.isCanceled():
        raise CancelledError("cancelled by the user")


def warn(feedback, message):
    """Report a warning: feedback.pushWarning where the feedback has it (QgsProcessingFeedback), else
    pushInfo; nothing where `feedback` or `message` is None."""
    if feedback is None or not message:
        return
    push = getattr(feedback, "pushWarning", None) or feedback.pushInfo
    push(message)


class _Scaled:
    """Feedback proxy mapping 0-100 % of a sub-step onto [start, stop] of the whole."""

    def __init__(self, feedback, start, stop):
        self.feedback, self.start, self.stop = feedback, start, stop

    def setProgress(self, percent):
        self.feedback.setProgress(self.start + (self.stop - self.start) * float(percent) / 100.0)

    def isCanceled(self):
        return self.feedback.isCanceled()

    def pushInfo(self, text):
        self.feedback.pushInfo(text)

    def pushWarning(self, text):
        warn(self.feedback, text)


def scaled(feedback, start, stop):
    """Feedback for a sub-step: its 0-100 % reported as start-stop % of `feedback` (None stays None)."""
    return None if feedback is None else _Scaled(feedback, start, stop)


class _Quiet(NullFeedback):
    """Feedback proxy that only forwards cancelling and warnings."""

    def __init__(self, feedback):
        self.feedback = feedback

    def isCanceled(self):
        return self.feedback.isCanceled()

    def pushWarning(self, text):
        warn(self.feedback, text)


def quiet(feedback):
    """Feedback for a repeated sub-step whose own messages and progress would be noise: cancelling and
    warnings only."""
    return None if feedback is None else _Quiet(feedback)


def gdal_callback(feedback):
    """A GDAL progress callback reporting to `feedback` (None: nothing); it stops GDAL when the user cancels,
    which the caller then raises as CancelledError (GDAL returns no dataset or an error)."""

    def callback(fraction, *_):
        if feedback is None:
            return 1
        if feedback.isCanceled():
            return 0
        feedback.setProgress(100.0 * fraction)
        return 1

    return callback
