"""Storage of multi-image points (matching/points.py's MultiPoints) beside a block.

Storage choice: a point folder `<block stem>.<kind>.<host>-<pid>-<8 hex>` next to the GeoPackage,
referenced from the block's `block_info` table (key = kind, value = the folder name relative to the
block). It holds the points in parts (`part-<k>.npz`: an uncompressed numpy archive of the part's two
tables, point ids ascending; store_points cuts a MultiPoints into parts of PART_POINTS points, a tiled
step writes one part per tile) and `index.json` (the format, the stats, and per part its file, point,
observation and group counts and id range). A step reads one part at a
time (`point_parts`, `load_arrays`), so its memory follows the part, not the scene; `load_points`
gives all of them at once, for the steps whose points are few (tie points) or small scenes. A
point folder of earlier versions (one `.npz` file) is read as one part.

Why not BLOB or attribute tables in the GeoPackage: millions of rows written through OGR feature by
feature take tens of seconds, a single BLOB hits SQLite's 1 GB value limit near 10 million points and
rewrites the whole database page chain, while an .npz of the structured arrays is written and read at
disk speed (tests/benchmarks/bench_points.py) and loads straight into the arrays the adjustment and the
surface steps use. For display, the points are also written as a point layer into the block
(`write_point_layer`), which can be rebuilt from the point folder at any time (most of that time is SQLite
building the R-tree spatial index, about 10 s per million points). A set of more than DISPLAY_POINTS points
is shown by a uniform subsample of about that many (a point is shown where its id, hashed by Knuth's
multiplicative hash, falls below the share): dense matching gives about one point per pixel, hundreds of
millions over a scene, which no display needs and whose layer would take longer to build than the matching.
The stored points are always all of them.

Versioned storage: a store never overwrites what the block references. The new point folder gets a new name
(and is written as a whole: atomic.atomic_dir); the new point layer is built under a staged name
(`<layer>__staged_<host>_<pid>`); then ONE transaction replaces the layer by the staged one, points
block_info at the new point folder with its counts and bumps the kind's generation (schema.GENERATIONS); only
then is the old point folder removed (only the block's own, named by its stem: a copied block file references
the original's folder, which stays). A kill at any moment leaves the old points, layer and counts, or the new
ones, never a mix; the staged layer and the point folder a killed store leaves behind are removed by the next
store once their writer has gone (atomic.owner_gone).

A store that finds far fewer points than the block holds (none, or below half of what the stored points give
at the new run's spacing: replacement.py) is refused before the layer is built, its new point folder removed,
unless `replace_fewer`. The spacing is the stats' SPACING key of the kind (the matching's grid in the
reference image, the tie point cell): a point folder without it is compared by its count alone.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import re
import secrets
import shutil
import sqlite3
import zipfile
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np
from osgeo import ogr

from .. import atomic, progress
from ..atomic import atomic_path
from ..crs import wgs84
from ..errors import InputError, StorageError
from ..matching.points import MultiPoints
from ..progress import Feedback
from ..sensors.base import SensorModel
from . import schema
from .replacement import Tally, check_replacement

FILE_FORMAT = "pushbroom-multipoints-1"
INDEX_FORMAT = "pushbroom-multipoints-parts-1"
INDEX = "index.json"
#: points per part of a point folder: about 50 MB of a three-image part in memory
PART_POINTS = 262_144
# a GeoPackage point geometry: header (magic, version, flags = little endian without envelope,
# srs id) and the WKB point
GPKG_POINT_DTYPE = np.dtype(
    [
        ("magic", "S2"),
        ("version", "u1"),
        ("flags", "u1"),
        ("srs_id", "<i4"),
        ("order", "u1"),
        ("type", "<u4"),
        ("x", "<f8"),
        ("y", "<f8"),
    ]
)
KINDS = ("mass_points", "tie_points")
#: the most points a display layer shows (module docstring)
DISPLAY_POINTS = 250_000
#: the step that makes each kind (named in errors)
MAKERS = {"mass_points": "pushbroom:matchpoints", "tie_points": "pushbroom:selecttiepoints"}
#: the stats key of each kind's spacing in the reference image (px; module docstring)
SPACING = {"mass_points": "spacing_px", "tie_points": "tie_cell"}

#: what a point layer is drawn with: (sensor model, image id, mean ellipsoidal height) of the image whose
#: observations are projected (write_point_layer)
Display = tuple[SensorModel, int, float]
#: a part's entry in a point folder's index (write_part): file, points, observations, first_id, last_id, groups
PartEntry = dict[str, Any]
#: writes the parts of a new point folder into the folder it is given; returns (their index entries, the run's stats)
Fill = Callable[[str], tuple[list[PartEntry], dict[str, Any]]]


def _folder(block_path: str | os.PathLike[str]) -> str:
    """The folder of the block's point folders: the real block file's (schema.real_path)."""
    return os.path.dirname(schema.real_path(block_path))


def _stem(block_path: str | os.PathLike[str]) -> str:
    """The name stem of the block's point folders: the real block file's (schema.real_path)."""
    return os.path.splitext(os.path.basename(schema.real_path(block_path)))[0]


def _point_folder_name(block_path: str | os.PathLike[str], kind: str) -> re.Pattern[str]:
    """The names of the point folders (and the one-file point stores of earlier versions) of `kind` beside the
    block: a versioned folder or .npz file (groups: writer host, pid), or the unversioned .npz of the first
    versions."""
    return re.compile(
        rf"^{re.escape(_stem(block_path))}\.{kind}(?:\.([A-Za-z0-9_]+)-(\d+)-[0-9a-f]{{8}}(?:\.npz)?"
        r"|\.npz)$"
    )


def point_folders(block_path: str | os.PathLike[str]) -> list[str]:
    """The paths of every point folder (or one-file point store) of the block beside it, of every kind: the
    referenced ones and those a killed store left."""
    folder = _folder(block_path)
    patterns = [_point_folder_name(block_path, kind) for kind in KINDS]
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    return [os.path.join(folder, name) for name in names if any(p.match(name) for p in patterns)]


def save_arrays(path: str, points: MultiPoints) -> str:
    """Write `points` (MultiPoints) to the .npz `path` atomically (one part of a point folder)."""
    with atomic_path(path, "the point file") as tmp:
        with open(tmp, "wb") as f:
            np.savez(
                f,
                format=np.array(FILE_FORMAT),
                points=points.points,
                observations=points.observations,
                stats=np.array(json.dumps(points.stats)),
            )
    return path


def _damaged(path: str, step: str, exc: BaseException) -> StorageError:
    return StorageError(f"the point file {path} is damaged ({exc}): it was cut short or overwritten; run {step} again")


def _read_part(path: str, step: str) -> MultiPoints:
    try:
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data.files or str(data["format"]) != FILE_FORMAT:
                raise InputError(f"{path} is not a Pushbroom point file")
            return MultiPoints(data["points"], data["observations"], json.loads(str(data["stats"])))
    except (zipfile.BadZipFile, EOFError, ValueError, KeyError, OSError) as exc:
        raise _damaged(path, step, exc) from None


def read_index(path: str, step: str = "the matching step") -> dict[str, Any] | None:
    """The index of the point folder `path` (module docstring), or None for a one-file point store."""
    if not os.path.exists(path):
        raise InputError(f"point file {path} is missing: run {step} again")
    if not os.path.isdir(path):
        return None
    return _folder_index(path, step)


def _folder_index(path: str, step: str) -> dict[str, Any]:
    """The index of the point folder `path` (read_index, for a path known to be a folder)."""
    try:
        with open(os.path.join(path, INDEX), encoding="utf-8") as f:
            index = json.load(f)
    except (OSError, ValueError) as exc:
        raise _damaged(path, step, exc) from None
    if index.get("format") != INDEX_FORMAT:
        raise InputError(f"{path} is not a Pushbroom point folder")
    return index


def read_stats(path: str, step: str = "the matching step") -> dict[str, Any]:
    """The stats of the points of the point folder `path` (a folder, or one .npz file)."""
    index = read_index(path, step)
    return index["stats"] if index is not None else _read_part(path, step).stats


def point_parts(path: str, step: str = "the matching step") -> list[str]:
    """The part files of the point folder `path` (a folder, or one .npz file), in point id order."""
    index = read_index(path, step)
    return [os.fspath(path)] if index is None else [os.path.join(path, p["file"]) for p in index["parts"]]


def load_arrays(path: str, step: str = "the matching step") -> MultiPoints:
    """Read the MultiPoints of a point folder written by `store_point_parts` (all parts), or of one part or
    .npz file written by `save_arrays`; a damaged file (cut short, overwritten) is a StorageError that
    names it."""
    index = read_index(path, step)
    if index is None:
        return _read_part(path, step)
    parts = [_read_part(p, step) for p in point_parts(path, step)]
    return MultiPoints(
        np.concatenate([p.points for p in parts]) if parts else None,
        np.concatenate([p.observations for p in parts]) if parts else None,
        index["stats"],
    )


def write_part(folder: str, k: int, points: MultiPoints) -> PartEntry:
    """Write `points` (MultiPoints, ids ascending, with their observations) as the k-th part of the point folder
    folder being written at `folder`; returns its index entry. What a tile task writes (store_point_parts)."""
    name = f"part-{k:05d}.npz"
    if len(points):  # an empty part is left out of the folder and its index
        save_arrays(os.path.join(folder, name), points)
    ids = points.points["id"]
    return {
        "file": name,
        "points": len(points),
        "observations": len(points.observations),
        "first_id": int(ids[0]) if len(ids) else None,
        "last_id": int(ids[-1]) if len(ids) else None,
        "groups": {str(g): n for g, n in points.group_counts().items()},
    }


def write_index(folder: str, entries: Iterable[PartEntry], stats: Mapping[str, Any]) -> None:
    """Write the index of the point folder at `folder` from its parts' entries (write_part) and `stats`."""
    entries = [e for e in entries if e["points"]]
    atomic.write_text(
        os.path.join(folder, INDEX),
        json.dumps(
            {"format": INDEX_FORMAT, "points": sum(e["points"] for e in entries), "stats": stats, "parts": entries},
            indent=1,
        ),
        "the point index",
    )


def split_parts(folder: str, points: MultiPoints, part_points: int | None = None) -> list[PartEntry]:
    """Write `points` (MultiPoints) into the point folder at `folder` as parts of `part_points` (default
    PART_POINTS) points in id order; returns their index entries."""
    part_points = int(part_points or PART_POINTS)
    order = np.argsort(points.points["id"], kind="stable")
    pts = points.points[order]
    obs = points.observations[np.lexsort((points.observations["image_id"], points.observations["point_id"]))]
    starts = np.arange(0, len(pts), part_points)
    bounds = np.searchsorted(obs["point_id"], [pts["id"][s] for s in starts] + [np.iinfo(np.int64).max])
    return [
        write_part(folder, k, MultiPoints(pts[a : a + part_points], obs[bounds[k] : bounds[k + 1]]))
        for k, a in enumerate(starts)
    ]


def _remove_orphan_point_folders(block_path: str, kind: str, keep: str) -> None:
    """Remove the point folders of `kind` other than `keep` whose writer has gone (unversioned ones: always)."""
    folder = _folder(block_path)
    pattern = _point_folder_name(block_path, kind)
    for name in os.listdir(folder):
        match = pattern.match(name)
        if (
            match
            and name != keep
            and (match.group(1) is None or atomic.owner_gone(match.group(1), int(match.group(2)), 0.0))
        ):
            _remove_point_folder(os.path.join(folder, name))


def _remove_point_folder(path: str) -> None:
    """Remove a point folder: a folder or, of earlier versions, one file."""
    if os.path.isdir(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _drop_layers(block_path: str, names: Sequence[str]) -> None:
    if names:
        with schema.transaction(block_path, "the clean-up of an interrupted store") as ds:
            for name in names:
                if ds.GetLayerByName(name) is not None:
                    ds.DeleteLayer(name)


def _drop_orphan_layers(block_path: str, layer_name: str) -> None:
    """Drop the staged layers of `layer_name` whose writer has gone (a killed store's)."""
    pattern = re.compile(rf"^{re.escape(layer_name)}__staged_([A-Za-z0-9_]+)_(\d+)$")
    ds = schema.open_block(block_path)
    names = [ds.GetLayer(k).GetName() for k in range(ds.GetLayerCount())]
    ds = None
    _drop_layers(
        block_path,
        [n for n in names if (m := pattern.match(n)) and atomic.owner_gone(m.group(1), int(m.group(2)), 0.0)],
    )


@contextlib.contextmanager
def _staged_layer(
    block_path: str, layer_name: str, points: MultiPoints | str, display: Display | None, feedback: Feedback | None
) -> Iterator[str | None]:
    """Build the point layer of `points` (a MultiPoints or a point folder; display = (model, image id,
    height)) under a staged name and
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


def _switch(ds: ogr.DataSource, staged: str | None, layer_name: str) -> None:
    """Inside the caller's transaction: the staged layer replaces `layer_name`."""
    if staged is None:
        return
    if ds.GetLayerByName(layer_name) is not None:
        ds.DeleteLayer(layer_name)
    ds.GetLayerByName(staged).Rename(layer_name)


def store_points(
    block_path: str,
    points: MultiPoints,
    kind: str = "mass_points",
    display: Display | None = None,
    feedback: Feedback | None = None,
    replace_fewer: bool = False,
) -> str:
    """Store `points` (MultiPoints) beside the block as a new point folder of `kind` and, given `display` = (sensor
    model, image id, mean height), as the block's point layer `kind` (`write_point_layer`), switched in one
    transaction (module docstring). Far fewer points than the block holds are refused (InputError, the block
    unchanged) unless `replace_fewer`. Returns the point folder path."""
    return store_point_parts(
        block_path, kind, lambda folder: (split_parts(folder, points), points.stats), display, feedback, replace_fewer
    )


def _spacing(stats: Mapping[str, Any] | None, kind: str) -> float | None:
    """The spacing (px) of the points of `kind` with run stats `stats`, or None where not recorded."""
    value = (stats or {}).get(SPACING[kind])
    return float(value) if isinstance(value, (int, float)) and value > 0 else None


def _tally(block_path: str, kind: str, stored_name: str | None, index: Mapping[str, Any]) -> Tally:
    """The Tally of the points of `kind` in the new point folder's `index` against the stored point folder `stored_name`
    (None: none); a stored point folder that is missing or damaged counts as none, so that it can be replaced."""
    name = kind.replace("_", " ")
    if not stored_name:
        return Tally(name, 0, index["points"])
    try:
        stored = read_index(os.path.join(_folder(block_path), stored_name))
    except (InputError, StorageError):  # missing or damaged: nothing to keep
        return Tally(name, 0, index["points"])
    if stored is None:  # a one-file point store of earlier versions: its count is in block_info
        return Tally(name, int(schema.read_info(block_path).get(f"{kind}_count") or 0), index["points"])
    old, new = _spacing(stored["stats"], kind), _spacing(index["stats"], kind)
    expected = stored["points"] * (old / new) ** 2 if old and new else None
    return Tally(name, stored["points"], index["points"], expected)


def store_point_parts(
    block_path: str,
    kind: str,
    fill: Fill,
    display: Display | None = None,
    feedback: Feedback | None = None,
    replace_fewer: bool = False,
) -> str:
    """`store_points` of points that `fill(folder)` writes into the new point folder (write_part: e.g. the
    tasks of a tiled step, each writing its parts, in the order of their ids) and returns as (index
    entries, stats). The layer is built part by part: memory follows the part. Far fewer points than the
    block holds are refused (InputError: the block keeps its points, layer and counts, the new folder is
    removed) unless `replace_fewer` (module docstring). Returns the point folder path."""
    if kind not in KINDS:
        raise InputError(f"point kind must be one of {KINDS}, not {kind!r}")
    what = f"the {kind.replace('_', ' ')}"
    schema.check_writable(block_path, what)
    old = schema.read_info(block_path).get(kind)
    name = f"{_stem(block_path)}.{kind}.{atomic.HOST}-{os.getpid()}-{secrets.token_hex(4)}"
    path = os.path.join(_folder(block_path), name)
    try:
        with atomic.atomic_dir(path, "the point folder") as tmp:
            entries, stats = fill(tmp)
            write_index(tmp, entries, stats)
        progress.step(feedback, 5)
        index = _folder_index(path, "the matching step")  # atomic_dir wrote a folder
        check_replacement(
            [_tally(block_path, kind, old, index)],
            replace_fewer,
            kind.replace("_", " "),
            MAKERS[kind],
            feedback=feedback,
        )
        groups = {1: 0, 2: 0, 3: 0}
        for entry in index["parts"]:
            for g, n in entry["groups"].items():
                groups[int(g)] = groups.get(int(g), 0) + n
        with _staged_layer(block_path, kind, path, display, progress.scaled(feedback, 5, 95)) as staged:
            with schema.transaction(block_path, what) as ds:
                _switch(ds, staged, kind)
                schema.write_info(
                    ds,
                    {
                        kind: name,
                        f"{kind}_count": index["points"],
                        **{f"{kind}_group{g}": n for g, n in sorted(groups.items())},
                    },
                    step=f"store {kind}",
                    message=f"{index['points']} points in {name}",
                )
                schema.bump(ds, kind)
    except BaseException:
        _remove_point_folder(path)
        raise
    if old and old != name and _point_folder_name(block_path, kind).match(old):
        # only this block's own folder: a copied block file references the original's, which stays
        _remove_point_folder(os.path.join(_folder(block_path), old))
    _remove_orphan_point_folders(block_path, kind, keep=name)
    progress.step(feedback, 100)
    return path


def point_folder(block_path: str, kind: str = "mass_points") -> str:
    """The point folder of the points of `kind` stored with the schema (InputError where there is none)."""
    info = schema.read_info(block_path)
    if kind not in info:
        raise InputError(
            f"block {block_path} has no {kind.replace('_', ' ')}: run {MAKERS.get(kind, 'the step')} first"
        )
    return os.path.join(_folder(block_path), info[kind])


def load_points(block_path: str, kind: str = "mass_points") -> MultiPoints:
    """The MultiPoints of `kind` stored with the schema, all parts at once."""
    return load_arrays(point_folder(block_path, kind), MAKERS.get(kind, "the step"))


def layer_source(block_path: str | os.PathLike[str], layer_name: str) -> str:
    """The OGR source string of a point layer of the schema."""
    return f"{os.fspath(block_path)}|layername={layer_name}"


def write_point_layer(
    block_path: str,
    layer_name: str,
    points: MultiPoints,
    model: SensorModel,
    image_id: int,
    height: float,
    feedback: Feedback | None = None,
) -> str:
    """Write `points` (MultiPoints) as the point layer `layer_name` (EPSG:4326; fields id, group, rho =
    rho_min) of the block, replacing an existing one in one switch (built under a staged name first, as
    `store_points` does). Display only: it can be rebuilt from the stored points at any time.

    Positions are the observations in image `image_id` projected with its sensor `model` at the
    ellipsoidal `height` (a mean height; no ray intersection, so the positions are off by the
    relief displacement of the height error: display only). Points without an observation in
    that image are left out. Returns the layer's OGR source string."""
    if not layer_name.isidentifier():
        raise InputError(f"a point layer name must be an identifier, not {layer_name!r}")
    schema.check_writable(block_path, f"the layer {layer_name}")
    with _staged_layer(
        block_path, layer_name, points, (model, image_id, height), progress.scaled(feedback, 0, 95)
    ) as staged:
        with schema.transaction(block_path, f"the layer {layer_name}") as ds:
            _switch(ds, staged, layer_name)
    progress.step(feedback, 100)
    return layer_source(block_path, layer_name)


def _parts_of(points: MultiPoints | str) -> list[MultiPoints | Callable[[], MultiPoints]]:
    """The parts to display: a MultiPoints as one part, or the part files of a point folder (read one at a
    time)."""
    if isinstance(points, MultiPoints):
        return [points]
    return [functools.partial(load_arrays, p) for p in point_parts(points)]


def _write_layer(
    block_path: str,
    layer_name: str,
    points: MultiPoints | str,
    model: SensorModel,
    image_id: int,
    height: float,
    feedback: Feedback | None = None,
) -> None:
    """Create the point layer `layer_name` of `points` (a MultiPoints, or a point folder read part by
    part) in the block (write_point_layer's content)."""
    what = f"the layer {layer_name}"
    with schema.transaction(block_path, what) as ds:
        if ds.GetLayerByName(layer_name) is not None:
            ds.DeleteLayer(layer_name)
        layer = ds.CreateLayer(
            layer_name, wgs84(), ogr.wkbPoint, options=["FID=fid", "GEOMETRY_NAME=geom", "SPATIAL_INDEX=NO"]
        )
        for name, kind in [("id", ogr.OFTInteger64), ("group", ogr.OFTInteger), ("rho", ogr.OFTReal)]:
            layer.CreateField(ogr.FieldDefn(name, kind))
    progress.step(feedback, 10)
    parts = _parts_of(points)
    index = None if isinstance(points, MultiPoints) else read_index(points)
    if index is not None:
        total = index["points"]
    else:  # a MultiPoints, or a one-file point store: its one part, read once
        first = parts[0] if isinstance(parts[0], MultiPoints) else parts[0]()
        parts, total = [first], len(first)
    share = min(1.0, DISPLAY_POINTS / max(total, 1))
    if share < 1.0:
        progress.ensure(feedback).pushInfo(
            f"the layer {layer_name} shows a uniform {100 * share:.1f} % of the "
            f"{total} points (at most {DISPLAY_POINTS}: display only; all are stored)"
        )
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    try:
        with contextlib.closing(sqlite3.connect(os.fspath(block_path), timeout=schema.BUSY_TIMEOUT_MS / 1000)) as db:
            with db:
                for k, part in enumerate(parts):
                    part = part if isinstance(part, MultiPoints) else part()
                    lon, lat = _insert_rows(db, layer_name, part, model, image_id, height, share)
                    if len(lon):
                        lo = np.minimum(lo, [lon.min(), lat.min()])
                        hi = np.maximum(hi, [lon.max(), lat.max()])
                    progress.step(feedback, 10 + 70 * (k + 1) / len(parts))
                if np.isfinite(lo).all():
                    db.execute(
                        "UPDATE gpkg_contents SET min_x = ?, min_y = ?, max_x = ?, max_y = ? WHERE table_name = ?",
                        (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]), layer_name),
                    )
    except sqlite3.OperationalError as exc:
        raise (
            schema.locked_error(block_path, what)
            if "locked" in str(exc)
            else atomic.storage_error(exc, block_path, what)
        ) from None
    progress.step(feedback, 80)
    with schema.transaction(block_path, what) as ds:
        ds.ExecuteSQL(f"SELECT CreateSpatialIndex('{layer_name}', 'geom')")
    progress.step(feedback, 100)


def _insert_rows(
    db: sqlite3.Connection,
    layer_name: str,
    points: MultiPoints,
    model: SensorModel,
    image_id: int,
    height: float,
    share: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Insert the rows of `points` seen in image `image_id` into the layer through `db`, of a `share` < 1
    those whose hashed id falls below it (module docstring); returns their (lon, lat)."""
    ids, col, row = points.observations_of(image_id)
    if share < 1.0:
        shown = (ids.astype(np.uint64) * np.uint64(2654435761)) % np.uint64(2**32) < np.uint64(share * 2**32)
        ids, col, row = ids[shown], col[shown], row[shown]
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
    # The rows go in through sqlite3 with the GeoPackage geometry blobs built by numpy: OGR's
    # feature-by-feature path is tens of times slower (tests/benchmarks/bench_points.py).
    blobs = np.zeros(len(ids), GPKG_POINT_DTYPE)
    blobs["magic"], blobs["flags"], blobs["srs_id"] = b"GP", 1, 4326
    blobs["order"], blobs["type"], blobs["x"], blobs["y"] = 1, 1, lon, lat
    raw = blobs.view(np.dtype((np.void, GPKG_POINT_DTYPE.itemsize)))
    rows = zip((memoryview(r).tobytes() for r in raw), ids.tolist(), group.tolist(), rho.astype(float).tolist())
    db.executemany(f'INSERT INTO "{layer_name}" (geom, id, "group", rho) VALUES (?, ?, ?, ?)', rows)
    return lon, lat
