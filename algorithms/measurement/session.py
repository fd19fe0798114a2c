"""The state and logic of one interactive measurement session on a block (issue 6), without Qt: the
measurement window (ui/measurement_window.py) presents it and forwards the user's actions to it.

State:
- `observations`: the block's control/check points and their image measurements as stored;
- `models` {image id: sensor model} and `residuals` (Block.residuals) of the block,
  read again after an adjustment (`adjusted`);
- `current`: the name of the current point (a stored point or the draft), or None;
- `draft`: store.put_point values of a new point not stored yet (no ground position, no measurement);
- `intended` {name: sigmas}: the a priori ground sigmas chosen for a provisional point;
- `pending` {image id: transfer.Transfer}: LSM transfers of the current point not accepted yet, and
  `transfer_notes` {image id: why the transfer into it failed}.

Invariants: `observations` equal the block after every edit, undo and redo (`reload`); `current` is
None, a stored point or the draft; `pending` and `transfer_notes` belong to `current` and are
cleared when it changes or vanishes (deleted, or its creation undone).

Persistence: every edit is written when its method returns, one SQLite transaction per store call
(edits.py); only the draft, the intended sigmas and the pending transfers live in memory, so a crash
loses no measurement. A point measured in an image before it has a ground position is stored at once
at a provisional one, the ray of that measurement intersected with the DEM (else the block's mean
height), with a priori ground sigmas PROVISIONAL_SIGMA (1 km): an adjustment treats it as a tie
point, never as control, and a reopened session recognises it. A ground position (a reference click,
typed coordinates) replaces it and gives it the intended sigmas (else the defaults).

Undo: the commands of each edit form one edits.Edit, handed to `record` (the window's undo stack)
once done; `undo(edit)` and `redo(edit)` replay it. An edit that fails midway raises after recording
the part that was done, so the block and the undo history agree.

Image coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel."""

import contextlib
import math
import os

from ..adjustment import control_points
from ..adjustment.control_points import DEFAULT_SIGMAS, ROLES
from ..block import Block
from ..errors import InputError
from ..height_range import mean_height
from ..sigmas import IMAGE_SIGMA
from . import georeferencer, prediction, transfer
from .edits import (
    DeleteMeasurement,
    DeletePoint,
    Edit,
    PutMeasurement,
    PutPoint,
    RenamePoint,
    ReplacePoints,
    point_values,
)

#: names of new points: POINT_PREFIX + 3 digits
POINT_PREFIX = "P"
#: a priori ground sigma (m) of a point whose ground position is provisional (module docstring)
PROVISIONAL_SIGMA = 1000.0
SIGMA_KEYS = ("sigma_e", "sigma_n", "sigma_h")


def is_provisional(values):
    """True for a point (record or put_point values) stored at a provisional ground position."""
    return all(float(values[k]) == PROVISIONAL_SIGMA for k in SIGMA_KEYS)


def residual_magnitudes(residual):
    """(|v| px, |w|) of an image residual (vx, vy, wx, wy): the residual's length and the largest
    normalised residual coordinate."""
    vx, vy, wx, wy = residual
    return math.hypot(vx, vy), max(abs(wx), abs(wy))


class MeasurementSession:
    """The measurement session on the block `block_path` (module docstring); `record(edit)` receives
    every edit done (default: none kept)."""

    def __init__(self, block_path, record=None):
        self.block_path = os.fspath(block_path)
        self.block = Block(self.block_path)
        self.record = record if record is not None else (lambda edit: None)
        self.store = self.block.measurement_store()
        images = self.block.images()
        self.image_names = {r["id"]: r["name"] for r in images}
        self.image_paths = {r["id"]: r["image_path"] for r in images}
        self.default_height = mean_height(self.block.height_range())
        self.models = self._read_models()
        self.residuals = self.block.residuals()
        self.current = None
        self.draft = None
        self.intended = {}
        self.pending = {}
        self.transfer_notes = {}
        self.observations = self.store.load()

    # --- the block on disk: the session reads and writes it through `block` (Block): the single edits
    # through `store` (its measurement store), an import's undo and redo in edits.ReplacePoints --------
    def _read_models(self):
        return self.block.models(list(self.image_names))

    def reload(self):
        """Read the points again; a current point that vanished (deleted, its creation undone) is
        dropped with its pending transfers."""
        self.observations = self.store.load()
        if self.point(self.current) is None and not self._is_draft(self.current):
            self.current, self.pending, self.transfer_notes = None, {}, {}

    def adjusted(self):
        """Read the models, the residuals and the points again, after an adjustment of the block."""
        self.models = self._read_models()
        self.residuals = self.block.residuals()
        self.reload()

    # --- queries --------------------------------------------------------------------------------------
    def image_id(self, name):
        """The block id of the image called `name`."""
        for image_id, image_name in self.image_names.items():
            if image_name == name:
                return image_id
        raise InputError(f"no image {name!r} in the block; its images are {', '.join(self.image_names.values())}")

    def check_image(self, image_id):
        """`image_id` as an int, or InputError when the block has no such image."""
        image_id = int(image_id)
        if image_id not in self.image_names:
            raise InputError(f"no image with id {image_id} in the block; its images are {self.image_names}")
        return image_id

    def _index(self, name):
        """Index of stored point `name` in observations.points, or None."""
        hit = (self.observations.points["name"] == name).nonzero()[0] if name is not None else ()
        return int(hit[0]) if len(hit) else None

    def point(self, name):
        """The stored POINT_DTYPE record of `name`, or None."""
        k = self._index(name)
        return None if k is None else self.observations.points[k]

    def _is_draft(self, name):
        return self.draft is not None and self.draft["name"] == name

    def values(self, name):
        """store.put_point keywords of point `name` (the stored record, else the draft)."""
        record = self.point(name)
        if record is not None:
            return point_values(record)
        if self._is_draft(name):
            return dict(self.draft)
        raise InputError(f"no point {name!r}: create it with New point")

    def measurements(self, name):
        """{image id: (col, row, sigma)} stored for point `name` (none for the draft or None)."""
        k, meas = self._index(name), self.observations.measurements
        if k is None:
            return {}
        mine = meas[meas["point"] == k]
        return {int(m["image_id"]): (float(m["col"]), float(m["row"]), float(m["sigma"])) for m in mine}

    def measured_in(self, image_id):
        """[(point name, col, row)] of the measurements stored in image `image_id`."""
        names, meas = self.observations.points["name"], self.observations.measurements
        return [(str(names[m["point"]]), float(m["col"]), float(m["row"])) for m in meas[meas["image_id"] == image_id]]

    def ground(self, name):
        """(lon, lat, h, provisional) of stored point `name`, or None (a draft, no point)."""
        record = self.point(name)
        if record is None:
            return None
        return float(record["lon"]), float(record["lat"]), float(record["h"]), is_provisional(record)

    def predictions(self, name):
        """{image id: (col, row)} of point `name` from the current models (None outside the image)."""
        ground = self.ground(name)
        return {} if ground is None else prediction.predict(self.models, *ground[:3])

    def current_positions(self):
        """{image id: (col, row)} of the current point in each image where it has one: its measurement,
        else its pending transfer, else its prediction."""
        if self.current is None:
            return {}
        measured = self.measurements(self.current)
        predicted = self.predictions(self.current)
        out = {}
        for image_id in self.image_names:
            t = self.pending.get(image_id)
            where = measured.get(image_id) or ((t.col, t.row) if t is not None else None) or predicted.get(image_id)
            if where is not None:
                out[image_id] = where[:2]
        return out

    def image_residual(self, name, image_id):
        """(vx, vy, wx, wy) of point `name` in image `image_id` in the last adjustment, or None."""
        return self.residuals[0].get((name, image_id))

    def residual_px(self):
        """{point name: RMS of its image residuals (px)} of the last adjustment."""
        return {name: g[3] for name, g in self.residuals[1].items()}

    def point_summaries(self):
        """One dict per stored point, in store order: name, role, h, count (images measured in),
        measured (their ids), images {image id: (|v|, |w|) of the last adjustment, or None} and
        ground ((dE, dN, dH, image RMS px) of the last adjustment, or None)."""
        image_res, ground = self.residuals
        meas = self.observations.measurements
        rows = []
        for k, p in enumerate(self.observations.points):
            name = str(p["name"])
            measured = set(meas["image_id"][meas["point"] == k].tolist())
            per_image = {}
            for image_id in self.image_names:
                res = image_res.get((name, image_id)) if image_id in measured else None
                per_image[image_id] = residual_magnitudes(res) if res is not None else None
            rows.append(
                {
                    "name": name,
                    "role": str(p["role"]),
                    "h": float(p["h"]),
                    "count": len(measured),
                    "measured": measured,
                    "images": per_image,
                    "ground": ground.get(name),
                }
            )
        return rows

    def free_name(self):
        """The first unused name P001, P002, ..."""
        used = set(self.observations.points["name"].tolist())
        k = 1
        while f"{POINT_PREFIX}{k:03d}" in used:
            k += 1
        return f"{POINT_PREFIX}{k:03d}"

    # --- the current point ------------------------------------------------------------------------------
    def select(self, name):
        """Make `name` (a stored point, the draft or None) current; pending transfers of another
        point are dropped."""
        if name != self.current:
            self.pending, self.transfer_notes = {}, {}
        self.current = name

    def select_point(self, name):
        """Make stored point `name` current."""
        if self.point(name) is None:
            raise InputError(f"no point {name!r} in the block")
        self.select(name)

    def _current(self):
        if self.current is None:
            raise InputError("no current point: create one with New point or select one")
        return self.current

    def new_point(self, name=None, role="control"):
        """Make a new point (default name: free_name()) current, as the draft: it is stored once it
        gets a ground position or a measurement. Returns its name."""
        name = name or self.free_name()
        if self.point(name) is not None:
            raise InputError(f"point {name} exists already: choose another name")
        if role not in ROLES:
            raise InputError(f"role {role!r} is not one of {', '.join(ROLES)}")
        sigma_e, sigma_n, sigma_h = DEFAULT_SIGMAS
        self.draft = {
            "name": name,
            "role": role,
            "lon": math.nan,
            "lat": math.nan,
            "h": math.nan,
            "sigma_e": sigma_e,
            "sigma_n": sigma_n,
            "sigma_h": sigma_h,
        }
        self.select(name)
        return name

    # --- edits --------------------------------------------------------------------------------------------
    @contextlib.contextmanager
    def _edit(self, text=None):
        """An Edit to add commands to; once the block is left (also by an exception) the points are
        read again and the edit, unless empty, is recorded."""
        edit = Edit(text)
        try:
            yield edit
        finally:
            if edit.commands:
                self.reload()
                self.record(edit)

    def undo(self, edit):
        """Undo a recorded `edit`; returns the messages of its commands that failed."""
        failures = edit.undo()
        self.reload()
        return failures

    def redo(self, edit):
        """Do an undone `edit` again; returns the messages of its commands that failed."""
        failures = edit.redo()
        self.reload()
        return failures

    def _put_point(self, edit, values):
        """Add to `edit` the creation or edit of point `values` (put_point keywords)."""
        record = self.point(values["name"])
        old = point_values(record) if record is not None else None
        edit.add(PutPoint(self.store, values, old))
        if self._is_draft(values["name"]):
            self.draft = None

    def edit_point(self, name, new_name=None, role=None, sigma_e=None, sigma_n=None, sigma_h=None):
        """Change the role and sigmas of point `name` and rename it (one edit; the draft changes in
        memory). Returns whether anything changed."""
        values = self.values(name)
        changes = {
            k: v
            for k, v in (("role", role), ("sigma_e", sigma_e), ("sigma_n", sigma_n), ("sigma_h", sigma_h))
            if v is not None and v != values[k]
        }
        stored = self.point(name) is not None
        rename = bool(new_name) and new_name != name
        if rename and self.point(new_name) is not None:
            raise InputError(f"point {new_name} exists already: choose another name")
        if not changes and not rename:
            return False
        if not stored:
            self.draft.update(changes)
            if rename:
                self.draft["name"] = new_name
                self._renamed(name, new_name)
            return True
        with self._edit(f"Edit point {name}") as edit:
            if changes:
                values.update(changes)
                self._put_point(edit, values)
            if rename:
                edit.add(RenamePoint(self.store, name, new_name, self._renamed))
        return True

    def _renamed(self, before, after):
        """Follow a rename (done or undone)."""
        if before in self.intended:
            self.intended[after] = self.intended.pop(before)
        if self.current == before:
            self.current = after

    def set_ground(self, lon, lat, h):
        """Set the current point's ground position: WGS 84 lon, lat (degrees), ellipsoidal h (m). A
        provisional point gets its intended sigmas (else the defaults); pending transfers are dropped."""
        name = self._current()
        values = self.values(name)
        if is_provisional(values):
            values.update(zip(SIGMA_KEYS, self.intended.pop(name, DEFAULT_SIGMAS)))
        values.update(lon=float(lon), lat=float(lat), h=float(h))
        with self._edit() as edit:
            self._put_point(edit, values)
        self.pending, self.transfer_notes = {}, {}

    def measure(self, image_id, col, row, dem=None):
        """Measure the current point at (col, row) in image `image_id`. The draft is stored first at
        the provisional ground position seen there (prediction.ground_from_click on `dem`, an
        algorithms.dem.Dem, else at the block's mean height)."""
        image_id, name = self.check_image(image_id), self._current()
        old = self.measurements(name).get(image_id)
        draft = None
        if self.point(name) is None:
            draft = self.values(name)
            lon, lat, h = prediction.ground_from_click(
                self.models[image_id], col, row, dem=dem, height=self.default_height
            )
            self.intended[name] = tuple(draft[k] for k in SIGMA_KEYS)
            draft.update(lon=lon, lat=lat, h=h, **dict.fromkeys(SIGMA_KEYS, PROVISIONAL_SIGMA))
        with self._edit(f"Measure {name} in {self.image_names[image_id]}") as edit:
            if draft is not None:
                self._put_point(edit, draft)
            edit.add(PutMeasurement(self.store, name, image_id, col, row, IMAGE_SIGMA, old, self.image_names[image_id]))
        self.pending.pop(image_id, None)
        self.transfer_notes.pop(image_id, None)

    def transfer(self, image_id: int, col: float, row: float) -> "dict[int, transfer.Transfer]":
        """LSM transfers of the current point's position (col, row) in image `image_id` into the images
        where it is not measured yet, at its ground height (transfer.transfer): the accepted ones
        become `pending`, the reasons of the others `transfer_notes`. Returns {image id: Transfer}."""
        image_id, name = int(image_id), self._current()
        measured = self.measurements(name)
        targets = [i for i in self.image_names if i != image_id and i not in measured]
        if not targets:
            return {}
        height = self.ground(name)[2]
        results = transfer.transfer(
            self.image_paths, self.models, transfer.Click(image_id, col, row), targets=targets, height=height
        )
        for target, t in results.items():
            if t.ok:
                self.pending[target] = t
            else:
                self.transfer_notes[target] = t.reason
        return results

    def accept_pending(self, image_id=None):
        """Store the pending transfers (of `image_id` only, or all) as measurements (one edit)."""
        ids = [i for i in self.pending if image_id is None or i == int(image_id)]
        if not ids:
            return
        name = self.current
        with self._edit(f"Accept transfers of {name}") as edit:
            for i in ids:
                t = self.pending[i]
                edit.add(
                    PutMeasurement(
                        self.store,
                        name,
                        i,
                        t.col,
                        t.row,
                        IMAGE_SIGMA,
                        self.measurements(name).get(i),
                        self.image_names[i],
                    )
                )
                del self.pending[i]

    def reject_pending(self, image_id=None):
        """Drop the pending transfers (of `image_id` only, or all)."""
        for i in [i for i in self.pending if image_id is None or i == int(image_id)]:
            del self.pending[i]

    def delete_measurement(self, image_id):
        """Delete the current point's measurement in image `image_id`; returns whether there was one."""
        image_id = int(image_id)
        old = self.measurements(self.current).get(image_id) if self.current is not None else None
        if old is None:
            return False
        with self._edit() as edit:
            edit.add(DeleteMeasurement(self.store, self.current, image_id, old, self.image_names[image_id]))
        return True

    def delete_point(self, name):
        """Delete stored point `name` with its measurements (one edit; returns True), or discard the
        draft `name` (returns False)."""
        if self.point(name) is None:
            if self._is_draft(name):
                self.draft = None
                self.select(None)
                return False
            raise InputError(f"no point {name!r} in the block")
        if name == self.current:
            self.current, self.pending, self.transfer_notes = None, {}, {}
        with self._edit() as edit:
            edit.add(DeletePoint(self.store, name))
        return True

    # --- files ------------------------------------------------------------------------------------------------
    def _replace_points(self, text, before, after):
        """Record an import that changed the block's points from `before` to `after` (Observations)."""
        with self._edit() as edit:
            edit.add(ReplacePoints(self.block, before, after, text), done=True)

    def import_csv(self, path, **options):
        """Merge the points of a CSV file (control_points.import_csv options) into the block (one
        edit); returns the block's points after it (Observations)."""
        before = self.store.load()
        after = control_points.import_csv(self.block, path, mode="merge", **options)
        self._replace_points(f"Import {os.path.basename(path)}", before, after)
        return after

    def export_csv(self, path):
        """Write the block's points as a CSV file (control_points.export_csv)."""
        control_points.export_csv(self.block, path)

    def import_points_file(self, path, image_id, map_crs=None, dem=None):
        """Merge a QGIS Georeferencer .points file measured in image `image_id` (one edit): map
        coordinates in the file's #CRS, else (as QGIS: the map's) in `map_crs` (crs.srs definition);
        heights from `dem`, else the block's mean height. Returns the points read (Observations)."""
        before = self.store.load()
        prefix = os.path.splitext(os.path.basename(path))[0][:24] + "_"
        read = georeferencer.read_points(
            path, int(image_id), dem=dem, height=self.default_height, default_crs=map_crs, prefix=prefix
        )
        after = self.block.save_control_points(read, mode="merge")
        self._replace_points(f"Import {os.path.basename(path)}", before, after)
        return read

    def export_points_file(self, path, image_id, crs=None):
        """Write the points measured in image `image_id` as a QGIS Georeferencer .points file with map
        coordinates in `crs` (georeferencer.write_points)."""
        georeferencer.write_points(path, self.store.load(), int(image_id), crs=crs)
