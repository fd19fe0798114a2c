"""Undoable edits of a block's control/check points and image measurements (the measurement session,
session.py).

A command performs one store call in `do()` and its inverse in `undo()`: the block's measurement store's
single edits (block/measurements.py) or, for an import, Block.save_control_points of the whole point set.
Each call is one committed SQLite transaction, so the block on disk always holds the state after the
last do or undo. An `Edit` groups the commands of one user action (e.g. storing a provisional point
and its first measurement) into one undo step: `redo()` does them in order, `undo()` undoes them in
reverse order."""

from ..errors import PushbroomError

#: the keyword arguments of store.put_point
POINT_KEYS = ("name", "role", "lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h")


def point_values(record):
    """{key: value} of a POINT_DTYPE record, as the keyword arguments of store.put_point."""
    return {key: (str(record[key]) if key in ("name", "role") else float(record[key])) for key in POINT_KEYS}


class Command:
    """One store call (`do`) and its inverse (`undo`); `text` names it for the undo history."""

    text = ""

    def do(self):
        raise NotImplementedError

    def undo(self):
        raise NotImplementedError


class PutPoint(Command):
    """Create point `values` (store.put_point keywords) or, with `old` (its values before), edit it."""

    def __init__(self, store, values, old=None):
        self.text = f"{'Edit' if old is not None else 'New'} point {values['name']}"
        self.store, self.values, self.old = store, dict(values), old

    def do(self):
        self.store.put_point(**self.values)

    def undo(self):
        if self.old is None:
            self.store.delete_point(self.values["name"])
        else:
            self.store.put_point(**self.old)


class RenamePoint(Command):
    """Rename point `old` to `new`; `renamed(before, after)` follows each do and undo."""

    def __init__(self, store, old, new, renamed=None):
        self.text = f"Rename point {old} to {new}"
        self.store, self.old, self.new, self.renamed = store, old, new, renamed

    def _rename(self, before, after):
        self.store.rename_point(before, after)
        if self.renamed is not None:
            self.renamed(before, after)

    def do(self):
        self._rename(self.old, self.new)

    def undo(self):
        self._rename(self.new, self.old)


class DeletePoint(Command):
    """Delete a point with its measurements; undo restores both."""

    def __init__(self, store, name):
        self.text = f"Delete point {name}"
        self.store, self.name, self.removed = store, name, None

    def do(self):
        self.removed = self.store.delete_point(self.name)

    def undo(self):
        self.store.restore(*self.removed)


class PutMeasurement(Command):
    """Measure point `name` at (col, row) in image `image_id`; `old` (col, row, sigma) is the
    measurement it replaces, None for a new one."""

    def __init__(self, store, name, image_id, col, row, sigma, old=None, image_name=None):
        self.text = f"Measure {name} in {image_name or f'image {image_id}'}"
        self.store, self.name, self.image_id = store, name, int(image_id)
        self.position, self.old = (float(col), float(row), float(sigma)), old

    def do(self):
        self.store.put_measurement(self.name, self.image_id, *self.position)

    def undo(self):
        if self.old is None:
            self.store.delete_measurement(self.name, self.image_id)
        else:
            self.store.put_measurement(self.name, self.image_id, *self.old)


class DeleteMeasurement(Command):
    """Remove the measurement of `name` in `image_id`; `old` is its (col, row, sigma) for undo."""

    def __init__(self, store, name, image_id, old, image_name=None):
        self.text = f"Delete the measurement of {name} in {image_name or f'image {image_id}'}"
        self.store, self.name, self.image_id, self.old = store, name, int(image_id), old

    def do(self):
        self.store.delete_measurement(self.name, self.image_id)

    def undo(self):
        self.store.put_measurement(self.name, self.image_id, *self.old)


class ReplacePoints(Command):
    """An import: the block's points `before` and `after` (Observations); do and undo store one of
    them whole (Block.save_control_points, one transaction; fewer points than stored too: an undo or a redo
    restores what the user had). The import itself is the first do: add it to its Edit with done=True."""

    def __init__(self, block, before, after, text):
        self.text = text
        self.block, self.before, self.after = block, before, after

    def do(self):
        self.block.save_control_points(self.after, mode="replace", replace_fewer=True)

    def undo(self):
        self.block.save_control_points(self.before, mode="replace", replace_fewer=True)


class Edit:
    """One undo step: the commands of one action, in the order done. `text` names it (default: the
    first command's text)."""

    def __init__(self, text=None):
        self._text = text
        self.commands = []

    @property
    def text(self):
        return self._text or (self.commands[0].text if self.commands else "")

    def add(self, command, done=False):
        """Do `command` (unless the caller has `done` it) and add it; a failing do raises and adds
        nothing."""
        if not done:
            command.do()
        self.commands.append(command)

    def undo(self):
        """Undo the commands in reverse order; returns the messages of those that failed (the others
        are still undone)."""
        return _attempt((command, command.undo) for command in reversed(self.commands))

    def redo(self):
        """Do the commands again in order; returns the messages of those that failed."""
        return _attempt((command, command.do) for command in self.commands)


def _attempt(calls):
    """Run every (command, bound method) of `calls`; the messages of those that failed."""
    failures = []
    for command, call in calls:
        try:
            call()
        except PushbroomError as exc:
            failures.append(f"cannot {command.text.lower()}: {exc}")
    return failures
