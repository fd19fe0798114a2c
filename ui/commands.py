"""Undo/redo of the measurement window: QUndoCommands around the MeasurementStore's methods
(algorithms/block/measurements.py). Every do and undo writes through the store at once, each in one
committed transaction, so the block on disk always equals what the window shows.

`push(stack, command)` performs the command first and pushes it only when that worked, so an
InputError (a name in use, a point that vanished) reaches the caller and leaves the stack as it
was; QUndoStack.push's own redo() is then skipped once. Later redo()/undo() calls, from Qt, must not
raise: a failure there is handed to `report` and the command made obsolete."""
from qgis.PyQt.QtWidgets import QUndoCommand

from ..algorithms.block import Block
from ..algorithms.errors import PushbroomError

POINT_KEYS = ("name", "role", "lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h")


def point_values(record):
    """{key: value} of a POINT_DTYPE record, as the keyword arguments of store.put_point."""
    return {key: (str(record[key]) if key in ("name", "role") else float(record[key])) for key in POINT_KEYS}


def push(stack, command, done=False):
    """Do `command` (raises on failure, nothing pushed) unless the caller has `done` it, then push it
    onto `stack` (QUndoStack)."""
    if not done:
        command.do()
    command.done = True
    stack.push(command)


class StoreCommand(QUndoCommand):
    """Base of the commands: subclasses implement do() and undo_(); `report(text)` receives the
    message of a failed redo/undo."""

    def __init__(self, text, report=None):
        super().__init__(text)
        self.done = False
        self.report = report

    def do(self):
        raise NotImplementedError

    def undo_(self):
        raise NotImplementedError

    def redo(self):
        if self.done:
            self.done = False
            return
        self._safely(self.do)

    def undo(self):
        self._safely(self.undo_)

    def _safely(self, action):
        try:
            action()
        except PushbroomError as exc:
            self.setObsolete(True)
            if self.report is not None:
                self.report(f"cannot {self.text().lower()}: {exc}")


class PutPoint(StoreCommand):
    """Create point `values` (store.put_point keywords) or, with `old` (its values before), edit it."""

    def __init__(self, store, values, old=None, report=None):
        text = f"{'Edit' if old is not None else 'New'} point {values['name']}"
        super().__init__(text, report)
        self.store, self.values, self.old = store, dict(values), old

    def do(self):
        self.store.put_point(**self.values)

    def undo_(self):
        if self.old is None:
            self.store.delete_point(self.values["name"])
        else:
            self.store.put_point(**self.old)


class RenamePoint(StoreCommand):
    """Rename point `old` to `new`; `renamed(before, after)` follows each do and undo."""

    def __init__(self, store, old, new, report=None, renamed=None):
        super().__init__(f"Rename point {old} to {new}", report)
        self.store, self.old, self.new, self.renamed = store, old, new, renamed

    def _rename(self, before, after):
        self.store.rename_point(before, after)
        if self.renamed is not None:
            self.renamed(before, after)

    def do(self):
        self._rename(self.old, self.new)

    def undo_(self):
        self._rename(self.new, self.old)


class DeletePoint(StoreCommand):
    """Delete a point with its measurements; undo restores both."""

    def __init__(self, store, name, report=None):
        super().__init__(f"Delete point {name}", report)
        self.store, self.name, self.removed = store, name, None

    def do(self):
        self.removed = self.store.delete_point(self.name)

    def undo_(self):
        self.store.restore(*self.removed)


class PutMeasurement(StoreCommand):
    """Measure point `name` at (col, row) in image `image_id`; `old` (col, row, sigma) is the
    measurement it replaces, None for a new one."""

    def __init__(self, store, name, image_id, col, row, sigma, old=None, image_name=None, report=None):
        super().__init__(f"Measure {name} in {image_name or f'image {image_id}'}", report)
        self.store, self.name, self.image_id = store, name, int(image_id)
        self.position, self.old = (float(col), float(row), float(sigma)), old

    def do(self):
        self.store.put_measurement(self.name, self.image_id, *self.position)

    def undo_(self):
        if self.old is None:
            self.store.delete_measurement(self.name, self.image_id)
        else:
            self.store.put_measurement(self.name, self.image_id, *self.old)


class DeleteMeasurement(StoreCommand):
    """Remove the measurement of `name` in `image_id`; `old` is its (col, row, sigma) for undo."""

    def __init__(self, store, name, image_id, old, image_name=None, report=None):
        super().__init__(f"Delete the measurement of {name} in {image_name or f'image {image_id}'}", report)
        self.store, self.name, self.image_id, self.old = store, name, int(image_id), old

    def do(self):
        self.store.delete_measurement(self.name, self.image_id)

    def undo_(self):
        self.store.put_measurement(self.name, self.image_id, *self.old)


class ReplacePoints(StoreCommand):
    """An import: the block's points `before` and `after` (Observations); do/undo store one of them
    whole (Block.save_control_points, one transaction). The import itself is the first do:
    push it with done=True."""

    def __init__(self, block_path, before, after, text, report=None):
        super().__init__(text, report)
        self.block_path, self.before, self.after = block_path, before, after

    def do(self):
        Block(self.block_path).save_control_points(self.after, mode="replace")

    def undo_(self):
        Block(self.block_path).save_control_points(self.before, mode="replace")
