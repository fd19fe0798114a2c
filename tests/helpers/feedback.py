"""A feedback object for engine tests (QgsProcessingFeedback's methods without QGIS)."""


class Feedback:
    """Keeps the messages (`messages`) and progress values (`progress`) it is given; asks to cancel
    after `cancel_after` isCanceled() checks (0: at once; None: never) or once the progress has
    reached `cancel_at` percent."""

    def __init__(self, cancel_after=None, cancel_at=None):
        self.messages, self.progress = [], []
        self.cancel_after, self.cancel_at, self.checks = cancel_after, cancel_at, 0

    def setProgress(self, percent):
        self.progress.append(float(percent))

    def isCanceled(self):
        self.checks += 1
        if self.cancel_at is not None and self.progress and self.progress[-1] >= self.cancel_at:
            return True
        return self.cancel_after is not None and self.checks > self.cancel_after

    def pushInfo(self, text):
        self.messages.append(text)
