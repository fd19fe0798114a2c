"""Multi-image points (mass points and tie points) and their storage beside a block.

A `MultiPoints` holds two numpy structured arrays:

- `points` (POINT_DTYPE), one row per ground point: id, group (1 two-ray, 2 three-ray from two
  combinations, 3 three-ray from all three combinations; paper K 3.3), `flags` (the combinations
  that matched it: COMB_A nadir-forward, COMB_B nadir-backward, COMB_C backward-forward; and
  REFINED where MPGC refined its search positions, refinement.py; the coarse-to-fine strategy's
  NCC_ONLY and EDGE: coarse_to_fine.py),
  rho_min (the smallest correlation coefficient of its combinations), rho_a/rho_b/rho_c (NaN
  where that combination did not match it) and dx/dy, the deviation of the doubly determined
  coordinates of group 3 points from their average (px of the forward image; NaN otherwise);
- `observations` (OBS_DTYPE), one row per image measurement: point id, block image id, col, row
  (GDAL convention), rho and the error-ellipse semi-axes (px) of the match that gave it (MPGC's
  for REFINED points, whose rho_min and rho_a/b/c stay the combinations' values). The
  first image of a combination is not matched (it is the template position): rho NaN, axes 0.
  Observations are sorted by point id, then image id.

`stats` is a small dict of run-level numbers (e.g. the count of group 3 points before the 3-sigma
test and the robust sigmas), kept with the points.

Storage choice: a sidecar `<block stem>.<kind>.<host>-<pid>-<8 hex>.npz` next to the GeoPackage
(uncompressed numpy archive of the two tables and the stats as JSON), written atomically
(algorithms/atomic.py) and referenced from the block's `block_info` table (key = kind, value = the file
name relative to the block). Why not BLOB or attribute tables in the GeoPackage: millions of rows written through OGR
feature by feature take tens of seconds, a single BLOB hits SQLite's 1 GB value limit near 10
million points and rewrites the whole database page chain, while an .npz of the structured arrays
is written and read at disk speed (2 million points with 5.3 million observations, 281 MB: save
0.35 s, load 0.23 s; tests/benchmarks/bench_points.py) and loads straight into the arrays the adjustment and the
surface steps use. For display, the points are also written as a point layer into the block
(`write_point_layer`), which can be rebuilt from the sidecar at any time (2 million points about
30 s, most of it OGR building the R-tree spatial index).

Versioned storage: a store never overwrites what the block references. The new sidecar gets a new name;
the new point layer is built under a staged name (`<layer>__staged_<host>_<pid>`); then ONE transaction
replaces the layer by the staged one, points block_info at the new sidecar with its counts and bumps the
kind's generation (block.GENERATIONS); only then is the old sidecar removed. A kill at any moment leaves
the old points, layer and counts, or the new ones, never a mix; the staged layer and the sidecar a killed
store leaves behind are removed by the next store once their writer has gone (atomic.owner_gone).
"""
import contextlib
import json
import os
import re
import secrets
import sqlite3
import zipfile

import numpy as np
from osgeo import ogr

from .. import atomic, block, progress
from ..atomic import atomic_path
from ..crs import wgs84
from ..errors import InputError, StorageError

# flag bits of POINT_DTYPE["flags"], one place for both matching strategies
COMB_A, COMB_B, COMB_C = 1, 2, 4
#: coarse-to-fine: a point MPGC did not accept (coarse_to_fine.py, step 4)
NCC_ONLY = 8
#: coarse-to-fine: a point matched as an edgel (coarse_to_fine.py, step 2)
EDGE = 16
#: region growing: a three-ray point whose search positions MPGC refined (refinement.py)
REFINED = 32

POINT_DTYPE = np.dtype([
    ("id", "i8"), ("group", "i1"), ("flags", "u1"), ("rho_min", "f4"),
    ("rho_a", "f4"), ("rho_b", "f4"), ("rho_c", "f4"), ("dx", "f4"), ("dy", "f4"),
])
OBS_DTYPE = np.dtype([
    ("point_id", "i8"), ("image_id", "i4"), ("col", "f8"), ("row", "f8"),
    ("rho", "f4"), ("semi_major", "f4"), ("semi_minor", "f4"),
])
FILE_FORMAT = "pushbroom-multipoints-1"
# a GeoPackage point geometry: header (magic, version, flags = little endian without envelope,
# srs id) and the WKB point
GPKG_POINT_DTYPE = np.dtype([("magic", "S2"), ("version", "u1"), ("flags", "u1"), ("srs_id", "<i4"),
                             ("order", "u1"), ("type", "<u4"), ("x", "<f8"), ("y", "<f8")])
KINDS = ("mass_points", "tie_points")
#: the step that makes each kind (named in errors)
MAKERS = {"mass_points": "pushbroom:matchpoints", "tie_points": "pushbroom:selecttiepoints"}


class MultiPoints:
    """Points seen in several images: `points` (POINT_DTYPE) and `observations` (OBS_DTYPE)."""

    def __init__(self, points=None, observations=None, stats=None):
        self.points = np.zeros(0, POINT_DTYPE) if points is None else np.asarray(points, POINT_DTYPE)
        self.observations = (np.zeros(0, OBS_DTYPE) if observations is None
                             else np.asarray(observations, OBS_DTYPE))
        self.stats = dict(stats or {})

    def __len__(self):
        return len(self.points)

    def __repr__(self):
        return f"MultiPoints({len(self.points)} points, {len(self.observations)} observations)"

    def image_ids(self):
        return np.unique(self.observations["image_id"])

    def observations_of(self, image_id):
        """(point ids, col, row) of the observations in image `image_id`, sorted by point id."""
        obs = self.observations[self.observations["image_id"] == image_id]
        return obs["point_id"], obs["col"], obs["row"]

    def coordinates(self, image_id):
        """col, row of every point in image `image_id`, in the order of `points` (NaN where the
        point has no observation there)."""
        col = np.full(len(self.points), np.nan)
        row = np.full(len(self.points), np.nan)
        ids, c, r = self.observations_of(image_id)
        pos = np.searchsorted(self.points["id"], ids)
        col[pos], row[pos] = c, r
        return col, row

    def subset(self, point_ids):
        """The points with the given ids and their observations (same stats)."""
        point_ids = np.asarray(point_ids, np.int64)
        keep = np.isin(self.points["id"], point_ids)
        obs_keep = np.isin(self.observations["point_id"], point_ids)
        return MultiPoints(self.points[keep], self.observations[obs_keep], self.stats)

    def group_counts(self):
        """{group: count} for groups 1, 2, 3."""
        return {g: int(np.count_nonzero(self.points["group"] == g)) for g in (1, 2, 3)}


def _folder(block_path):
    return os.path.dirname(os.path.abspath(os.fspath(block_path)))


def _stem(block_path):
    return os.path.splitext(os.path.basename(os.fspath(block_path)))[0]


def save_arrays(path, points):
    """Write `points` (MultiPoints) to the .npz `path` atomically."""
    with atomic_path(path, "the point file") as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, format=np.array(FILE_FORMAT), points=points.points, observations=points.observations,
                     stats=np.array(json.dumps(points.stats)))
    return path


def load_arrays(path, step="the matching step"):
    """Read a MultiPoints .npz written by `save_arrays`; a damaged file (cut short, overwritten) is a
    StorageError that names it."""
    if not os.path.exists(path):
        raise InputError(f"point file {path} is missing: run {step} again")
    try:
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data.files or str(data["format"]) != FILE_FORMAT:
                raise InputError(f"{path} is not a Pushbroom point file")
            return MultiPoints(data["points"], data["observations"], json.loads(str(data["stats"])))
    except (zipfile.BadZipFile, EOFError, ValueError, KeyError, OSError) as exc:
        raise StorageError(f"the point file {path} is damaged ({exc}): it was cut short or overwritten; run {step} "
                           "again") from None


def _remove_orphan_sidecars(block_path, kind, keep):
    """Remove the sidecars of `kind` other than `keep` whose writer has gone (unversioned ones: always)."""
    folder = _folder(block_path)
    pattern = re.compile(rf"^{re.escape(_stem(block_path))}\.{kind}(?:\.([A-Za-z0-9_]+)-(\d+)-[0-9a-f]{{8}})?\.npz$")
    for name in os.listdir(folder):
        match = pattern.match(name)
        if match and name != keep and (match.group(1) is None
                                       or atomic.owner_gone(match.group(1), int(match.group(2)), 0.0)):
            with contextlib.suppress(OSError):
                os.unlink(os.path.join(folder, name))


def _drop_layers(block_path, names):
    if names:
        with block.transaction(block_path, "the clean-up of an interrupted store") as ds:
            for name in names:
                if ds.GetLayerByName(name) is not None:
                    ds.DeleteLayer(name)


def _drop_orphan_layers(block_path, layer_name):
    """Drop the staged layers of `layer_name` whose writer has gone (a killed store's)."""
    pattern = re.compile(rf"^{re.escape(layer_name)}__staged_([A-Za-z0-9_]+)_(\d+)$")
    ds = block.open_block(block_path)
    names = [ds.GetLayer(k).GetName() for k in range(ds.GetLayerCount())]
    ds = None
    _drop_layers(block_path, [n for n in names if (m := pattern.match(n))
                              and atomic.owner_gone(m.group(1), int(m.group(2)), 0.0)])


@contextlib.contextmanager
def _staged_layer(block_path, layer_name, points, display, feedback):
    """Build the point layer of `points` (display = (model, image id, height)) under a staged name and
    yield that name (None without `display`); dropped again where the switch did not happen."""
    if display is None:
        yield None
        return
    _drop_orphan_layers(block_path, layer_name)
    staged = f"{layer_name}__staged_{atomic.HOST}_{os.getpid()}"
    try:
        _write_layer(block_path, staged, points, *display, feedback=feedback)
        yield staged
    except BaseException:
        with contextlib.suppress(Exception):
            _drop_layers(block_path, [staged])
        raise


def _switch(ds, staged, layer_name):
    """Inside the caller's transaction: the staged layer replaces `layer_name`."""
    if staged is None:
        return
    if ds.GetLayerByName(layer_name) is not None:
        ds.DeleteLayer(layer_name)
    ds.GetLayerByName(staged).Rename(layer_name)


def save_points(block_path, points, kind="mass_points", display=None, feedback=None):
    """Store `points` beside the block as a new sidecar of `kind` and, given `display` = (sensor model,
    image id, mean height), as the block's point layer `kind` (`write_point_layer`), switched in one
    transaction (module docstring). Returns the sidecar path."""
    if kind not in KINDS:
        raise InputError(f"point kind must be one of {KINDS}, not {kind!r}")
    what = f"the {kind.replace('_', ' ')}"
    block.check_writable(block_path, what)
    old = block.read_info(block_path).get(kind)
    name = f"{_stem(block_path)}.{kind}.{atomic.HOST}-{os.getpid()}-{secrets.token_hex(4)}.npz"
    path = os.path.join(_folder(block_path), name)
    try:
        save_arrays(path, points)
        progress.step(feedback, 5)
        with _staged_layer(block_path, kind, points, display, progress.scaled(feedback, 5, 95)) as staged:
            with block.transaction(block_path, what) as ds:
                _switch(ds, staged, kind)
                block.write_info(ds, {kind: name, f"{kind}_count": len(points),
                                      **{f"{kind}_group{g}": n for g, n in points.group_counts().items()}},
                                 step=f"store {kind}", message=f"{len(points)} points in {name}")
                block.bump(ds, kind)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(path)
        raise
    if old and old != name:
        with contextlib.suppress(OSError):
            os.unlink(os.path.join(_folder(block_path), old))
    _remove_orphan_sidecars(block_path, kind, keep=name)
    progress.step(feedback, 100)
    return path


def load_points(block_path, kind="mass_points"):
    """The MultiPoints of `kind` stored with the block."""
    info = block.read_info(block_path)
    if kind not in info:
        raise InputError(f"block {block_path} has no {kind.replace('_', ' ')}: run {MAKERS.get(kind, 'the step')} "
                         "first")
    return load_arrays(os.path.join(_folder(block_path), info[kind]), MAKERS.get(kind, "the step"))


def layer_source(block_path, layer_name):
    """The OGR source string of a point layer of the block."""
    return f"{os.fspath(block_path)}|layername={layer_name}"


def write_point_layer(block_path, layer_name, points, model, image_id, height, feedback=None):
    """Write `points` (MultiPoints) as the point layer `layer_name` (EPSG:4326; fields id, group, rho =
    rho_min) of the block, replacing an existing one in one switch (built under a staged name first, as
    `save_points` does). Display only: it can be rebuilt from the stored points at any time.

    Positions are the observations in image `image_id` projected with its sensor `model` at the
    ellipsoidal `height` (a mean height; no ray intersection, so the positions are off by the
    relief displacement of the height error: display only). Points without an observation in
    that image are left out. Returns the layer's OGR source string."""
    if not layer_name.isidentifier():
        raise InputError(f"a point layer name must be an identifier, not {layer_name!r}")
    block.check_writable(block_path, f"the layer {layer_name}")
    with _staged_layer(block_path, layer_name, points, (model, image_id, height),
                       progress.scaled(feedback, 0, 95)) as staged:
        with block.transaction(block_path, f"the layer {layer_name}") as ds:
            _switch(ds, staged, layer_name)
    progress.step(feedback, 100)
    return layer_source(block_path, layer_name)


def _write_layer(block_path, layer_name, points, model, image_id, height, feedback=None):
    """Create the point layer `layer_name` of `points` in the block (write_point_layer's content)."""
    ids, col, row = points.observations_of(image_id)
    # rows in a spatially coherent order (strips of 64 px): the R-tree builds several times faster
    order = np.lexsort((col, np.floor(row / 64.0)))
    ids, col, row = ids[order], col[order], row[order]
    pos = np.searchsorted(points.points["id"], ids)
    group = points.points["group"][pos]
    rho = points.points["rho_min"][pos]
    if len(ids):
        lon, lat = model.image_to_ground(col, row, np.full(len(col), float(height)))
        lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    else:
        lon = lat = np.zeros(0)
    what = f"the layer {layer_name}"
    with block.transaction(block_path, what) as ds:
        if ds.GetLayerByName(layer_name) is not None:
            ds.DeleteLayer(layer_name)
        layer = ds.CreateLayer(layer_name, wgs84(), ogr.wkbPoint,
                               options=["FID=fid", "GEOMETRY_NAME=geom", "SPATIAL_INDEX=NO"])
        for name, kind in [("id", ogr.OFTInteger64), ("group", ogr.OFTInteger), ("rho", ogr.OFTReal)]:
            layer.CreateField(ogr.FieldDefn(name, kind))
    progress.step(feedback, 10)
    # The rows go in through sqlite3 with the GeoPackage geometry blobs built by numpy: OGR's
    # feature-by-feature path costs about 35 us a point (70 s for 2 million), this about 1 us.
    blobs = np.zeros(len(ids), GPKG_POINT_DTYPE)
    blobs["magic"], blobs["flags"], blobs["srs_id"] = b"GP", 1, 4326
    blobs["order"], blobs["type"], blobs["x"], blobs["y"] = 1, 1, lon, lat
    raw = blobs.view(np.dtype((np.void, GPKG_POINT_DTYPE.itemsize)))
    rows = zip((memoryview(r).tobytes() for r in raw), ids.tolist(), group.tolist(),
               rho.astype(float).tolist())
    try:
        with contextlib.closing(sqlite3.connect(os.fspath(block_path), timeout=block.BUSY_TIMEOUT_MS / 1000)) as db:
            with db:
                db.executemany(f'INSERT INTO "{layer_name}" (geom, id, "group", rho) VALUES (?, ?, ?, ?)', rows)
                if len(ids):
                    db.execute("UPDATE gpkg_contents SET min_x = ?, min_y = ?, max_x = ?, max_y = ? "
                               "WHERE table_name = ?", (float(lon.min()), float(lat.min()), float(lon.max()),
                                                        float(lat.max()), layer_name))
    except sqlite3.OperationalError as exc:
        raise (block.locked_error(block_path, what) if "locked" in str(exc)
               else atomic.storage_error(exc, block_path, what)) from None
    progress.step(feedback, 80)
    with block.transaction(block_path, what) as ds:
        ds.ExecuteSQL(f"SELECT CreateSpatialIndex('{layer_name}', 'geom')")
    progress.step(feedback, 100)
