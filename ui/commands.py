"""The measurement window's undo stack: one QUndoCommand per edit of its MeasurementSession
(algorithms/measurement/edits.py), pushed once the session has done it, so QUndoStack.push's own
redo() is skipped once. Later redo()/undo() calls come from Qt and must not raise: the messages of
failed store calls go to `report` and the command is made obsolete."""

from qgis.PyQt.QtWidgets import QUndoCommand


class EditCommand(QUndoCommand):
    """The done `edit` of `session`; `report(text)` receives the message of a failed redo/undo."""

    def __init__(self, session, edit, report=None):
        super().__init__(edit.text)
        self.session, self.edit, self.report = session, edit, report
        self.done = True

    def redo(self):
        if self.done:
            self.done = False
            return
        self._failed(self.session.redo(self.edit))

    def undo(self):
        self._failed(self.session.undo(self.edit))

    def _failed(self, messages):
        if messages:
            self.setObsolete(True)
        for text in messages:
            if self.report is not None:
                self.report(text)
