"""Residuals of the last bundle adjustment, kept in the block for the measurement window.

Written by `write_residuals` inside the transaction that stores the adjusted models
(pushbroom:bundleadjust), replacing what an earlier adjustment stored; the rows and what they mean
are adjustment/residual_rows.py's:

- table `measurement_residuals` (point_name, image_id, role, vx, vy, wx, wy): per image measurement
  of a control or check point, its residual (px) and normalised residual;
- table `point_residuals` (point_name, role, dE, dN, dH, image_rms_px): per point, its ground
  residuals (m) and the RMS of its image residual coordinates;
- field `residual_px` of the `control_points` layer: that RMS (NULL for points without residuals,
  e.g. measured in fewer than two images or added after the adjustment), for styling the map layer.

`load_residuals` returns the residuals of the points the block holds now: those of points removed
or renamed since are absent (a point created later under an old name shows the old residuals
until the next adjustment)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from osgeo import ogr

from . import control_points as cp, schema

MEASUREMENT_TABLE, POINT_TABLE, FIELD = "measurement_residuals", "point_residuals", "residual_px"
MEASUREMENT_FIELDS = [("point_name", ogr.OFTString), ("image_id", ogr.OFTInteger), ("role", ogr.OFTString)] + [
    (key, ogr.OFTReal) for key in ("vx", "vy", "wx", "wy")
]
POINT_FIELDS = [("point_name", ogr.OFTString), ("role", ogr.OFTString)] + [
    (key, ogr.OFTReal) for key in ("dE", "dN", "dH", "image_rms_px")
]


def _table(ds: ogr.DataSource, name: str, fields: Sequence[tuple[str, int]]) -> ogr.Layer:
    """The (emptied) residual table `name` of an open block, created if missing."""
    layer = ds.GetLayerByName(name)
    if layer is None:
        return schema.create_layer(ds, name, ogr.wkbNone, None, fields)
    ds.ExecuteSQL(f"DELETE FROM {name}")
    return layer


def _write(layer: ogr.Layer, fields: Sequence[tuple[str, int]], rows: Iterable[Sequence[Any]]) -> None:
    for row in rows:
        feat = ogr.Feature(layer.GetLayerDefn())
        for (key, kind), value in zip(fields, row):
            if kind == ogr.OFTReal and not np.isfinite(value):
                feat.SetFieldNull(key)
            else:
                feat[key] = value.item() if isinstance(value, np.generic) else value
        layer.CreateFeature(feat)


def write_residuals(
    ds: ogr.DataSource, meas_rows: Sequence[Sequence[Any]], point_rows: Sequence[Sequence[Any]]
) -> None:
    """Replace the residual tables and the control_points layer's residual_px of the open block `ds` by
    `residual_rows`' rows, inside the caller's transaction."""
    rms = {name: row[-1] for name, *row in point_rows}
    _write(_table(ds, MEASUREMENT_TABLE, MEASUREMENT_FIELDS), MEASUREMENT_FIELDS, meas_rows)
    _write(_table(ds, POINT_TABLE, POINT_FIELDS), POINT_FIELDS, point_rows)
    points, _ = cp.layers(ds)
    if points.GetLayerDefn().GetFieldIndex(FIELD) < 0:
        points.CreateField(ogr.FieldDefn(FIELD, ogr.OFTReal))
    for feat in list(points):
        value = rms.get(feat["name"], np.nan)
        if np.isfinite(value):
            feat[FIELD] = float(value)
        else:
            feat.SetFieldNull(FIELD)
        points.SetFeature(feat)


def load_residuals(block_path: str) -> tuple[dict[tuple[str, int], tuple[float, ...]], dict[str, tuple[float, ...]]]:
    """({(point name, image id): (vx, vy, wx, wy)}, {point name: (dE, dN, dH, image_rms_px)}) of the
    last adjustment, for the points the block holds now (NaN where a value is undefined); two empty
    dicts before any adjustment."""
    ds = schema.open_block(block_path)
    points = ds.GetLayerByName(cp.LAYER)
    tables = ds.GetLayerByName(MEASUREMENT_TABLE), ds.GetLayerByName(POINT_TABLE)
    if points is None or None in tables:
        return {}, {}
    names = {feat["name"] for feat in points}

    def values(feat: ogr.Feature, keys: Sequence[str]) -> tuple[float, ...]:
        return tuple(np.nan if feat[k] is None else float(feat[k]) for k in keys)

    image = {
        (f["point_name"], f["image_id"]): values(f, ("vx", "vy", "wx", "wy"))
        for f in tables[0]
        if f["point_name"] in names
    }
    ground = {
        f["point_name"]: values(f, ("dE", "dN", "dH", "image_rms_px")) for f in tables[1] if f["point_name"] in names
    }
    return image, ground
