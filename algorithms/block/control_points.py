"""The control/check point layer and image measurement table of a block.

The point layer `control_points` (EPSG:4326 point Z: lon, lat, ellipsoidal h; fields name, role, lon, lat,
h, sigma_e, sigma_n, sigma_h, and residual_px once a bundle adjustment has run, see residuals.py) and the
table `image_measurements` (point_name, image_id, col, row, sigma). `save_control_points` replaces or
merges both in one SQLite transaction, so an import either lands whole or leaves the block as it was;
one that leaves far fewer points, measured points or measurements than the block holds is refused
(replacement.py) unless asked for. measurements.py edits single points and measurements. The CSV format and its parsing:
adjustment/control_points.py."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from osgeo import ogr

from .. import progress
from ..adjustment.control_points import ROLES, summary
from ..adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from ..crs import wgs84
from ..errors import InputError
from ..progress import Feedback
from . import schema
from .images import image_ids
from .replacement import Tally, check_replacement

MODES = ("replace", "merge")
LAYER, TABLE = "control_points", "image_measurements"
POINT_FIELDS = [("name", ogr.OFTString), ("role", ogr.OFTString)] + [
    (key, ogr.OFTReal) for key in ("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h")
]
MEAS_FIELDS = [
    ("point_name", ogr.OFTString),
    ("image_id", ogr.OFTInteger),
    ("col", ogr.OFTReal),
    ("row", ogr.OFTReal),
    ("sigma", ogr.OFTReal),
]


def merge(old: Observations, new: Observations) -> Observations:
    """`old` updated by `new`: a point of `new` replaces the point of the same name (role,
    coordinates, sigmas; in old's order) or is appended; its measurements replace old's in the
    same images, old's measurements in other images are kept."""
    known = set(old.points["name"])
    names = list(old.points["name"]) + [n for n in new.points["name"] if n not in known]
    index = {n: i for i, n in enumerate(names)}
    points = np.zeros(len(names), POINT_DTYPE)
    points[: len(old.points)] = old.points
    points[[index[n] for n in new.points["name"]]] = new.points
    by_key: dict[tuple[int, int], tuple[int, int, float, float, float]] = {}
    for obs in (old, new):
        for m in obs.measurements:
            key = (index[obs.points["name"][m["point"]]], int(m["image_id"]))
            by_key[key] = (key[0], key[1], m["col"], m["row"], m["sigma"])
    return Observations(points, np.array(list(by_key.values()), MEAS_DTYPE)).sorted().check()


def layers(ds: ogr.DataSource) -> tuple[ogr.Layer, ogr.Layer]:
    """The control_points layer and image_measurements table of an open block (created if missing, with the
    triggers that count their changes: schema.control_point_triggers)."""
    points = ds.GetLayerByName(LAYER) or schema.create_layer(ds, LAYER, ogr.wkbPoint25D, wgs84(), POINT_FIELDS)
    table = ds.GetLayerByName(TABLE) or schema.create_layer(ds, TABLE, ogr.wkbNone, None, MEAS_FIELDS)
    schema.control_point_triggers(ds, LAYER, TABLE)
    return points, table


def write_point(layer: ogr.Layer, p: np.void, feat: ogr.Feature | None = None) -> None:
    """Store point record `p` (POINT_DTYPE) in the control_points layer: as a new feature, or into
    `feat` (an existing feature of the layer; its other fields, such as residual_px, kept)."""
    new = feat is None
    if feat is None:
        feat = ogr.Feature(layer.GetLayerDefn())
    for name, _ in POINT_FIELDS:
        feat[name] = p[name].item()
    geom = ogr.Geometry(ogr.wkbPoint25D)
    geom.AddPoint(float(p["lon"]), float(p["lat"]), float(p["h"]))
    feat.SetGeometry(geom)
    (layer.CreateFeature if new else layer.SetFeature)(feat)


def write_measurement(table: ogr.Layer, name: str, m: np.void) -> None:
    """A new row of the image_measurements table: measurement `m` (MEAS_DTYPE) of point `name`."""
    feat = ogr.Feature(table.GetLayerDefn())
    feat["point_name"] = name
    for key, _ in MEAS_FIELDS[1:]:
        feat[key] = m[key].item()
    table.CreateFeature(feat)


def read_stored(ds: ogr.DataSource, block_path: str) -> Observations:
    """The Observations stored in the open block `ds` (see load_control_points)."""
    points_layer, table = ds.GetLayerByName(LAYER), ds.GetLayerByName(TABLE)
    if points_layer is None:
        return Observations()
    rows = [tuple(feat[name] for name, _ in POINT_FIELDS) for feat in points_layer]
    points = np.array(rows, POINT_DTYPE) if rows else np.zeros(0, POINT_DTYPE)
    index = {n: i for i, n in enumerate(points["name"])}
    meas = []
    for feat in table if table is not None else []:
        if feat["point_name"] not in index:
            raise InputError(
                f"block {block_path}: image measurement of unknown point {feat['point_name']!r}; "
                "import the points again"
            )
        meas.append((index[feat["point_name"]], feat["image_id"], feat["col"], feat["row"], feat["sigma"]))
    return Observations(points, np.array(meas, MEAS_DTYPE)).sorted()


def tallies(stored: Observations, new: Observations) -> list[Tally]:
    """The counts `save_control_points` compares (replacement.py) of the Observations `stored` and `new`:
    points, points measured in at least one image, image measurements."""

    def counts(obs: Observations) -> tuple[int, int, int]:
        return (len(obs.points), len(set(obs.measurements["point"].tolist())), len(obs.measurements))

    return [
        Tally(name, a, b)
        for name, a, b in zip(
            ("control and check points", "measured points", "image measurements"), counts(stored), counts(new)
        )
    ]


def load_control_points(block_path: str) -> Observations:
    """The control/check points stored in the block and their measurements (image ids = block
    image ids); empty Observations when none were imported."""
    ds = schema.open_block(block_path)
    return read_stored(ds, block_path)


def save_control_points(
    block_path: str,
    observations: Observations,
    mode: str = "replace",
    feedback: Feedback | None = None,
    names: Mapping[str, int] | None = None,
    replace_fewer: bool = False,
) -> Observations:
    """Store `observations` (control/check points only) in the block, replacing its points
    (mode "replace") or updating them (mode "merge", see `merge`), in one SQLite transaction:
    on any error or a cancel the block keeps its earlier points. What would leave far fewer points,
    measured points or image measurements than the block holds (`tallies`, replacement.py) is refused with
    an InputError before anything is written, unless `replace_fewer`. `names`: {image name: id} of the
    block (read from it if not given). Returns what is stored. A block locked by another writer is
    waited for (schema.transaction); an OGR/SQLite failure is a StorageError."""
    if mode not in MODES:
        raise InputError(f"the import mode must be one of {', '.join(MODES)}, not {mode!r}")
    observations.check()
    roles = set(observations.points["role"].tolist()) - set(ROLES)
    if roles:
        raise InputError(f"only control and check points are stored with the block, not {', '.join(roles)} points")
    names = names or image_ids(block_path)
    known = set(names.values())
    unknown = sorted(set(observations.measurements["image_id"].tolist()) - known)
    if unknown:
        raise InputError(f"measurements in image id(s) {unknown}, which the block {block_path} does not have")
    with schema.transaction(block_path, "the points") as ds:
        stored = read_stored(ds, block_path)
        if mode == "merge":
            observations = merge(stored, observations)
        check_replacement(
            tallies(stored, observations),
            replace_fewer,
            "control and check points",
            "pushbroom:importpoints",
            "To add the file's points to the block's, import them with MODE merge.",
            feedback,
        )
        points_layer, table = layers(ds)
        ds.ExecuteSQL(f"DELETE FROM {TABLE}")
        ds.ExecuteSQL(f"DELETE FROM {LAYER}")
        for k, p in enumerate(observations.points):
            progress.step(feedback, 80.0 * k / max(len(observations.points), 1))
            write_point(points_layer, p)
        for m in observations.measurements:
            write_measurement(table, observations.points["name"][m["point"]].item(), m)
        progress.step(feedback, 90.0)
        ds.ExecuteSQL(f"RECOMPUTE EXTENT ON {LAYER}")
        point_roles = observations.points["role"]
        schema.write_info(
            ds,
            {
                "control_points": int((point_roles == "control").sum()),
                "check_points": int((point_roles == "check").sum()),
                "image_measurements": len(observations.measurements),
            },
            step="importpoints",
            message=f"{mode}: " + summary(observations, names),
        )
    progress.ensure(feedback).setProgress(100.0)
    return observations
