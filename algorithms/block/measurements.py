"""Single edits of a block's control/check points and their image measurements (the measurement
window, issue 6), in the block's layer `control_points` and table `image_measurements`
(control_points.py).

Every edit is ONE SQLite transaction, committed before the method returns: a killed process loses
nothing already returned, and an edit that fails (a refused value, a locked or broken file) leaves
the block as it was. Each edit opens the block anew (no connection kept between edits, so edits from
a background adjustment or QGIS's own layer never meet stale state), takes the write lock first
(schema.transaction: waiting up to BUSY_TIMEOUT_MS for another writer) and updates block_info's counts control_points,
check_points and image_measurements in the same transaction, without a run_log row per edit.

Records handed back for undo: points as POINT_DTYPE records; measurements as MEAS_DTYPE records
whose `point` is 0 (they belong to the one point the call is about)."""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterable, Iterator
from typing import Any

import numpy as np
from osgeo import ogr

from ..adjustment.control_points import NAME_LENGTH, ROLES
from ..adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from ..errors import InputError
from ..sigmas import IMAGE_SIGMA
from . import control_points as cp, schema
from .images import read_images


def _quoted(text: object) -> str:
    """`text` as an SQL string literal."""
    return "'" + str(text).replace("'", "''") + "'"


def _record(array: np.ndarray) -> np.void:
    """The record (np.void) a 0-d structured `array` holds."""
    return array[()]  # type: ignore[return-value]  # numpy's stubs type a 0-d array's [()] as an array


def check_name(name: str) -> str:
    """The point name `name`, or InputError: 1 to 32 printable characters (numpy's text drops a NUL at the end), no
    leading or trailing spaces."""
    name = str(name)
    if not name.strip() or len(name) > NAME_LENGTH or not name.isprintable():
        raise InputError(f"a point name must have 1 to {NAME_LENGTH} printable characters, got {name!r}")
    if name != name.strip():
        raise InputError(f"a point name must not begin or end with spaces, got {name!r}")
    return name


def point_record(
    name: str, role: str, lon: float, lat: float, h: float, sigma_e: float, sigma_n: float, sigma_h: float
) -> np.void:
    """A checked POINT_DTYPE record (InputError naming the bad value)."""
    name = check_name(name)
    if role not in ROLES:
        raise InputError(f"point {name}: the role must be one of {', '.join(ROLES)}, not {role!r}")
    try:
        values = [float(v) for v in (lon, lat, h, sigma_e, sigma_n, sigma_h)]
    except (TypeError, ValueError):
        raise InputError(
            f"point {name}: coordinates and sigmas must be numbers, got {[lon, lat, h, sigma_e, sigma_n, sigma_h]}"
        ) from None
    lon, lat, h = values[:3]
    if not all(math.isfinite(v) for v in values[:3]):
        raise InputError(f"point {name}: lon {lon}, lat {lat}, h {h} must all be finite numbers")
    if abs(lat) > 90.0 or abs(lon) > 360.0:
        raise InputError(
            f"point {name}: lon {lon}, lat {lat} are not WGS 84 degrees (are they swapped, or projected coordinates?)"
        )
    if not all(math.isfinite(s) and s > 0 for s in values[3:]):
        raise InputError(f"point {name}: the sigmas east, north, height must be positive, got {values[3:]} m")
    record = np.zeros((), POINT_DTYPE)
    record["name"], record["role"] = name, role
    for key, value in zip(("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h"), values):
        record[key] = value
    return _record(record)


def _point_of(feat: ogr.Feature) -> np.void:
    """The POINT_DTYPE record of a control_points feature."""
    return _record(np.array(tuple(feat[key] for key, _ in cp.POINT_FIELDS), POINT_DTYPE))


def _measurement_of(feat: ogr.Feature) -> np.void:
    """The MEAS_DTYPE record (point 0) of an image_measurements row."""
    return _record(np.array((0, feat["image_id"], feat["col"], feat["row"], feat["sigma"]), MEAS_DTYPE))


def _find(layer: ogr.Layer, where: str) -> ogr.Feature | None:
    """The first feature of `layer` matching the SQL condition `where`, or None."""
    layer.SetAttributeFilter(where)
    try:
        return layer.GetNextFeature()
    finally:
        layer.SetAttributeFilter(None)


def _all(layer: ogr.Layer, where: str) -> list[ogr.Feature]:
    layer.SetAttributeFilter(where)
    try:
        return list(layer)
    finally:
        layer.SetAttributeFilter(None)


class MeasurementStore:
    """Edits of the points and measurements of the block `block_path` (module docstring)."""

    def __init__(self, block_path: str | os.PathLike[str]) -> None:
        self.path = os.fspath(block_path)
        self.images: dict[int, dict[str, Any]] = {int(r["id"]): r for r in read_images(self.path)}

    # -- reading --------------------------------------------------------------------------------

    def load(self) -> Observations:
        """The block's control/check points and their measurements (Observations; image ids are
        the block's, measurements ordered by point, then image id)."""
        return cp.load_control_points(self.path)

    def snapshot(self, name: str) -> tuple[np.void, np.ndarray] | None:
        """(point record, its measurements) as stored, or None: what restore() needs to put it back."""
        ds = schema.open_block(self.path)
        points, table = ds.GetLayerByName(cp.LAYER), ds.GetLayerByName(cp.TABLE)
        feat = _find(points, f"name = {_quoted(name)}") if points is not None else None
        if feat is None:
            return None
        rows = _all(table, f"point_name = {_quoted(name)}") if table is not None else []
        return _point_of(feat), self._measurements(rows)

    # -- edits ----------------------------------------------------------------------------------

    @contextlib.contextmanager
    def _edit(self) -> Iterator[tuple[ogr.DataSource, ogr.Layer, ogr.Layer]]:
        """(data source, points layer, measurement table) inside one `transaction`, with
        block_info's counts written before the commit."""
        with schema.transaction(self.path) as ds:
            points, table = cp.layers(ds)
            yield ds, points, table
            self._write_counts(ds)

    @staticmethod
    def _write_counts(ds: ogr.DataSource) -> None:
        counts = {"control_points": 0, "check_points": 0}
        result = ds.ExecuteSQL(f"SELECT role, COUNT(*) AS n FROM {cp.LAYER} GROUP BY role")
        for feat in result:
            if feat["role"] in ROLES:
                counts[f"{feat['role']}_points"] = feat["n"]
        ds.ReleaseResultSet(result)
        result = ds.ExecuteSQL(f"SELECT COUNT(*) AS n FROM {cp.TABLE}")
        counts["image_measurements"] = result.GetNextFeature()["n"]
        ds.ReleaseResultSet(result)
        schema.write_info(ds, counts)

    @staticmethod
    def _stored_point(points: ogr.Layer, name: str) -> ogr.Feature | None:
        """The feature of point `name` in the points layer, or None."""
        return _find(points, f"name = {_quoted(name)}")

    def _point_feature(self, points: ogr.Layer, name: str) -> ogr.Feature:
        """The feature of point `name` in the points layer (InputError where there is none)."""
        feat = self._stored_point(points, name)
        if feat is None:
            raise InputError(f"the block has no point {name!r}")
        return feat

    def put_point(
        self, name: str, role: str, lon: float, lat: float, h: float, sigma_e: float, sigma_n: float, sigma_h: float
    ) -> np.void | None:
        """Create the point `name` or update its role, WGS 84 lon/lat (degrees), ellipsoidal h (m)
        and a priori sigmas (m); its measurements stay. Returns the record it replaced, or None."""
        record = point_record(name, role, lon, lat, h, sigma_e, sigma_n, sigma_h)
        with self._edit() as (_, points, _table):
            feat = self._stored_point(points, record["name"])
            old = None if feat is None else _point_of(feat)
            cp.write_point(points, record, feat)
        return old

    def rename_point(self, old: str, new: str) -> None:
        """Rename point `old` to `new` (a name not in use); its measurements follow."""
        new = check_name(new)
        if new == old:
            return
        with self._edit() as (ds, points, _table):
            feat = self._point_feature(points, old)
            if self._stored_point(points, new) is not None:
                raise InputError(f"point {new} exists already: choose another name, or delete that point first")
            feat["name"] = new
            points.SetFeature(feat)
            ds.ExecuteSQL(f"UPDATE {cp.TABLE} SET point_name = {_quoted(new)} WHERE point_name = {_quoted(old)}")

    def delete_point(self, name: str) -> tuple[np.void, np.ndarray]:
        """Delete point `name` and its measurements; returns (point record, measurements) for restore()."""
        with self._edit() as (_, points, table):
            feat = self._point_feature(points, name)
            rows = _all(table, f"point_name = {_quoted(name)}")
            record, meas = _point_of(feat), self._measurements(rows)
            for row in rows:
                table.DeleteFeature(row.GetFID())
            points.DeleteFeature(feat.GetFID())
        return record, meas

    def restore(self, record: np.void | np.ndarray, measurements: np.ndarray) -> None:
        """Store point `record` (POINT_DTYPE) with exactly these `measurements` (MEAS_DTYPE; their
        `point` field is ignored): the undo of delete_point, or of any edit given a snapshot()."""
        record = np.asarray(record, POINT_DTYPE).reshape(-1)
        if record.size != 1:
            raise InputError(f"restore takes one point record, got {record.size}")
        p = point_record(*(record[0][key].item() for key, _ in cp.POINT_FIELDS))
        meas = np.asarray(measurements, MEAS_DTYPE).reshape(-1)
        for m in meas:
            self._check_measurement(p["name"], m["image_id"], m["col"], m["row"], m["sigma"])
        with self._edit() as (_, points, table):
            cp.write_point(points, p, self._stored_point(points, p["name"]))
            for row in _all(table, f"point_name = {_quoted(p['name'])}"):
                table.DeleteFeature(row.GetFID())
            for m in meas:
                cp.write_measurement(table, p["name"].item(), m)

    def _check_measurement(
        self, name: str, image_id: int, col: float, row: float, sigma: float
    ) -> tuple[int, float, float, float]:
        """(image id, col, row, sigma) checked against the block's images (InputError naming the problem)."""
        try:
            image_id, col, row, sigma = int(image_id), float(col), float(row), float(sigma)
        except (TypeError, ValueError):
            raise InputError(
                f"point {name}: image id, col, row and sigma must be numbers, got {[image_id, col, row, sigma]}"
            ) from None
        if image_id not in self.images:
            raise InputError(
                f"point {name}: the block has no image with id {image_id} (its images: "
                + ", ".join(f"{i} {r['name']}" for i, r in self.images.items())
                + ")"
            )
        image = self.images[image_id]
        if not (
            math.isfinite(col) and math.isfinite(row) and 0.0 <= col <= image["cols"] and 0.0 <= row <= image["rows"]
        ):
            raise InputError(
                f"point {name}: ({col}, {row}) lies outside image {image['name']} "
                f"({image['cols']} x {image['rows']} px)"
            )
        if not (math.isfinite(sigma) and sigma > 0):
            raise InputError(f"point {name}: the measurement sigma must be positive, got {sigma} px")
        return image_id, col, row, sigma

    def put_measurement(
        self, name: str, image_id: int, col: float, row: float, sigma: float = IMAGE_SIGMA
    ) -> np.void | None:
        """Measure point `name` at (col, row) in block image `image_id` (a priori sigma px), replacing
        an earlier measurement there. Returns the measurement it replaced, or None."""
        image_id, col, row, sigma = self._check_measurement(name, image_id, col, row, sigma)
        m = _record(np.array((0, image_id, col, row, sigma), MEAS_DTYPE))
        with self._edit() as (_, points, table):
            self._point_feature(points, name)
            feat = _find(table, f"point_name = {_quoted(name)} AND image_id = {image_id}")
            if feat is None:
                cp.write_measurement(table, str(name), m)
                return None
            old = _measurement_of(feat)
            for key in ("col", "row", "sigma"):
                feat[key] = m[key].item()
            table.SetFeature(feat)
        return old

    def delete_measurement(self, name: str, image_id: int) -> np.void | None:
        """Remove the measurement of point `name` in image `image_id`; returns it, or None when there
        was none."""
        with self._edit() as (_, _points, table):
            feat = _find(table, f"point_name = {_quoted(name)} AND image_id = {int(image_id)}")
            if feat is None:
                return None
            table.DeleteFeature(feat.GetFID())
        return _measurement_of(feat)

    @staticmethod
    def _measurements(rows: Iterable[ogr.Feature]) -> np.ndarray:
        meas = np.array([tuple(_measurement_of(f).tolist()) for f in rows], MEAS_DTYPE)
        return meas[np.argsort(meas["image_id"], kind="stable")]
