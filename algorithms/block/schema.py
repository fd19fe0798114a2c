"""The block GeoPackage's schema, its opening and its transactions.

Tables: `block_info` (key/value: format version, creation time, default CRS, terrain height range,
references to the point files beside the block, generation counters), `images` (images.py),
`footprints` (polygon layer, EPSG:4326) and `run_log` (one row per processing step); the point layers
(points.py), the control points (control_points.py) and the residual tables (residuals.py) are added by
the steps that make them.

Every write after creation is one SQLite transaction (`transaction`) that takes the write lock first, waiting
up to BUSY_TIMEOUT_MS for another writer (QGIS saving an edit, another step) and then failing with a message
that says what to do; nothing is half-stored. Every connection waits the same way for other connections' locks.

Failures are said in Pushbroom's words, with what to do (SQLite's own words would give wrong advice):
- a lock held beyond BUSY_TIMEOUT_MS names the program holding it where Linux tells (`lock_holder`, from
  /proc/locks), and says that nothing was stored: wait for it or close it, then run the step again;
- a file that is not a whole block (an SQLite database that is no GeoPackage, a GeoPackage without Pushbroom's
  tables, a file cut short or overwritten: `damage`) is named as such: restore it from a copy;
- a block this user may not change is refused before a step computes (`write_access_error`): the file itself
  must be writable, and so must its folder, where SQLite creates its journal (`<block>-journal`) for every change.

Generations. block_info holds a counter per part of the block a computation reads: `generation_<part>` for
GENERATIONS. A step that computes from the block for a long time (the bundle adjustment) reads them first
(`generations`) and stores its results only if they are unchanged (`transaction(..., expect=...)`), so a
result computed from a control set that an import or an edit replaced meanwhile is refused, not stored
beside the new set. The point files and the models bump theirs in their own transactions; the control
points' counter is bumped by SQLite triggers on the `control_points` layer and the `image_measurements`
table (`control_point_triggers`), so edits made in QGIS's own attribute table count too."""

from __future__ import annotations

import contextlib
import datetime
import json
import os
import pwd
import stat
from collections.abc import Iterator, Mapping, Sequence

from osgeo import gdal, ogr, osr

from ..atomic import storage_error
from ..crs import wgs84
from ..errors import InputError, StorageError
from ..gdal_errors import reported_here

FORMAT_VERSION = "1"
IMAGE_FIELDS = [
    ("name", ogr.OFTString),
    ("image_path", ogr.OFTString),
    ("orientation_path", ogr.OFTString),
    ("model_kind", ogr.OFTString),
    ("sensor", ogr.OFTString),
    ("cols", ogr.OFTInteger),
    ("rows", ogr.OFTInteger),
    ("model", ogr.OFTString),
]
#: the images table's field of the supplied models (missing in blocks of format 1 made before it)
SUPPLIED = "supplied_model"


def real_path(path: str | os.PathLike[str]) -> str:
    """The block's one identity: the real path of `path` (symbolic links resolved), where its point folders
    live beside it and under whose name they are recorded."""
    return os.path.realpath(os.fspath(path))


#: the files SQLite keeps beside a database while it writes (rollback journal, write-ahead log and its index)
JOURNAL_SUFFIXES = ("-journal", "-wal", "-shm")


def journals(path: str | os.PathLike[str]) -> list[str]:
    """The SQLite journal files of the block `path` (which exist only while a connection writes)."""
    return [os.fspath(path) + suffix for suffix in JOURNAL_SUFFIXES]


def create_layer(
    ds: ogr.DataSource, name: str, geom_type: int, srs: osr.SpatialReference | None, fields: Sequence[tuple[str, int]]
) -> ogr.Layer:
    """A new layer (or table, geom_type wkbNone) with an integer fid and the given (name, OFT type) fields."""
    layer = ds.CreateLayer(name, srs, geom_type, options=["FID=fid"])
    for field_name, field_type in fields:
        layer.CreateField(ogr.FieldDefn(field_name, field_type))
    return layer


def create_schema(path: str | os.PathLike[str]) -> ogr.DataSource:
    """A new, empty block GeoPackage at `path` (its tables, format version); returns the data source."""
    ogr.UseExceptions()
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(os.fspath(path))
    info = create_layer(ds, "block_info", ogr.wkbNone, None, [("key", ogr.OFTString), ("value", ogr.OFTString)])
    feat = ogr.Feature(info.GetLayerDefn())
    feat["key"], feat["value"] = "format_version", FORMAT_VERSION
    info.CreateFeature(feat)
    create_layer(ds, "images", ogr.wkbNone, None, IMAGE_FIELDS + [(SUPPLIED, ogr.OFTString)])
    create_layer(ds, "footprints", ogr.wkbPolygon, wgs84(), [("image_id", ogr.OFTInteger), ("name", ogr.OFTString)])
    create_layer(
        ds,
        "run_log",
        ogr.wkbNone,
        None,
        [("time", ogr.OFTString), ("step", ogr.OFTString), ("parameters", ogr.OFTString), ("message", ogr.OFTString)],
    )
    return ds


#: ms a connection waits for another connection's lock (QGIS saving an edit of one of the block's layers, a step
#: storing its results) before it gives up with a StorageError
BUSY_TIMEOUT_MS = 10000
#: the parts of a block whose changes a long computation must not miss (module docstring)
GENERATIONS = ("control_points", "tie_points", "mass_points", "models")


def _execute(ds: ogr.DataSource, sql: str) -> None:
    result = ds.ExecuteSQL(sql)
    if result is not None:
        ds.ReleaseResultSet(result)


def lock_holder(path: str) -> str:
    """'another program (<name>, process <pid>)' holding a write lock on the file `path` (else any lock; Linux's
    /proc/locks), 'this program (<name>, process <pid>)' where it is this process (another connection: QGIS
    editing the block's layers), or 'another program' where unknown."""
    try:
        info = os.stat(path)
        with open("/proc/locks") as f:
            lines = f.read().splitlines()
    except OSError:
        return "another program"
    device = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    holders = []
    for line in lines:  # "1: POSIX  ADVISORY  WRITE 1234 fe:00:5678 1073741824 1073742335"; "->": waiting
        fields = line.split()
        if "->" not in fields and len(fields) >= 6 and fields[5] == device and fields[4].isdigit():
            holders.append((fields[3] != "WRITE", int(fields[4])))
    if not holders:
        return "another program"
    pid = min(holders)[1]
    try:
        with open(f"/proc/{pid}/comm") as f:
            program = f.read().strip()
    except OSError:
        program = "a program"
    return f"{'this' if pid == os.getpid() else 'another'} program ({program}, process {pid})"


def locked_error(block_path: str, what: str, reading: bool = False) -> StorageError:
    """StorageError for a block another connection keeps locked beyond BUSY_TIMEOUT_MS; `reading`: the lock
    (an exclusive one) keeps this step from even reading the block."""
    who = lock_holder(block_path)
    if reading:
        return StorageError(
            f"cannot read the block {block_path}: {who} holds an exclusive lock on it (waited "
            f"{BUSY_TIMEOUT_MS / 1000:g} s), so nothing can read or write it meanwhile. Let that "
            "program finish or close it (an SQLite tool with an unfinished transaction, another "
            "Pushbroom step), then run this step again; nothing was changed"
        )
    return StorageError(
        f"cannot store {what} in the block {block_path}: {who} keeps it locked (waited "
        f"{BUSY_TIMEOUT_MS / 1000:g} s). Save or stop the edits of its layers in QGIS, or wait for the "
        "other Pushbroom step to finish, then run this one again; nothing was stored"
    )


def _is_locked(exc: BaseException) -> bool:
    text = str(exc).lower()
    return "locked" in text or "busy" in text


def _user(uid: int) -> str:
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return f"uid {uid}"


def _owner(path: str) -> str:
    info = os.stat(path)
    return f"it belongs to {_user(info.st_uid)}, permissions {stat.filemode(info.st_mode)}"


def write_access_error(block_path: str, what: str) -> StorageError | None:
    """StorageError where this user may not change the block (module docstring): the file not writable, or
    its folder, where SQLite creates the journal of every change; None where both are writable, or where there
    is no block (open_block says so)."""
    path = os.path.abspath(block_path)
    if not os.path.isfile(path):
        return None
    folder = os.path.dirname(path)
    me = _user(os.geteuid())
    start = f"cannot store {what} in the block {block_path}"
    for target, kind in ((path, "file"), (folder, "folder")):
        if os.access(target, os.W_OK | (os.X_OK if kind == "folder" else 0)):
            continue
        try:
            read_only = os.statvfs(target).f_flag & os.ST_RDONLY
        except OSError:
            read_only = False
        if read_only:
            return StorageError(
                f"{start}: the {kind} is on a read-only file system. Copy the block with its point "
                "folders to a writable disk; nothing was stored"
            )
        if kind == "file":
            return StorageError(
                f"{start}: the block file is not writable by you (user {me}; {_owner(target)}). "
                "Have its owner give you write permission (chmod, chown), or work on a copy of the "
                "block, with its point folders beside it, in a folder of yours; nothing was stored"
            )
        return StorageError(
            f"{start}: its folder {folder} is not writable by you (user {me}; {_owner(target)}), and "
            f"SQLite must create a journal there ({os.path.basename(path)}-journal) to change the "
            "block. Have the folder's owner give you write permission, or move the block with its "
            "point folders to a folder you can write; nothing was stored"
        )
    return None


#: the first bytes of every SQLite database file
SQLITE_HEADER = b"SQLite format 3\x00"


def damage(path: str) -> str:
    """How the SQLite file `path` is cut short, or '': less than a header, no whole number of its pages, or
    fewer pages than its header records (told only where no journal beside it may hold the rest). Only for a
    file that failed to open: closing a file releases the POSIX locks this process's SQLite holds on it."""
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            head = f.read(100)
    except OSError:
        return ""
    if not head or not SQLITE_HEADER.startswith(head[:16]):
        return ""
    if len(head) < 100:
        return f"the file holds {size} bytes, less than the 100 of an SQLite header"
    if any(os.path.exists(journal) for journal in journals(path)):
        return ""
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    pages = int.from_bytes(head[28:32], "big")
    counted = head[92:96] == head[24:28]  # the header's page count is valid (SQLite's file format, 1.3.7)
    if counted and size < pages * page:
        return f"the file holds {size} bytes, its header records {pages} pages of {page} bytes ({pages * page})"
    if page < 512 or size % page:
        return f"the file holds {size} bytes, not a whole number of its {page}-byte pages"
    return ""


def damaged_error(path: str, cause: str = "") -> InputError:
    """InputError: the file `path` is a damaged block (`damage`, else SQLite's `cause`)."""
    why = damage(path) or (f"SQLite: {cause}" if cause else "")
    return InputError(
        f"the block {path} is damaged{f' ({why})' if why else ''}: it was cut short or overwritten (an "
        "interrupted copy or download, a full disk, another program writing into it). Restore it from a "
        "copy, or make the block again with pushbroom:createblock"
    )


def _not_a_block(path: str, why: str) -> InputError:
    return InputError(f"{path} is not a Pushbroom block ({why}): give the .gpkg that pushbroom:createblock made")


def open_block(path: str | os.PathLike[str], update: bool = False) -> ogr.DataSource:
    """The block's OGR data source, waiting up to BUSY_TIMEOUT_MS for other connections' locks; InputError
    if `path` is no Pushbroom block (no file, not a GeoPackage, a GeoPackage of another program, a damaged
    file), StorageError if it cannot be opened (locked, no permission; module docstring)."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"no block at {path}")
    ogr.UseExceptions()
    with reported_here():  # GDAL's own lines of a file refused here ("bad application_id") are not printed
        ds = _open(path, update)
        if ds is None:
            raise damaged_error(path) if damage(path) else _not_a_block(path, "not a GeoPackage")
        if ds.GetDriver().GetName() != "GPKG":
            raise _not_a_block(path, f"an {ds.GetDriver().GetName()} database, not a GeoPackage")
        if ds.GetLayerByName("block_info") is None:
            if damage(path):
                raise damaged_error(path)
            raise _not_a_block(
                path, "a GeoPackage without Pushbroom's block_info table, perhaps made by another program"
            )
    _execute(ds, f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    images = ds.GetLayerByName("images")
    defn = images.GetLayerDefn() if images is not None else None
    fields = {defn.GetFieldDefn(k).GetName() for k in range(defn.GetFieldCount())} if defn is not None else set()
    missing = [name for name, _ in IMAGE_FIELDS if name not in fields]
    if missing:
        raise InputError(
            f"{path} is not a Pushbroom block: its images table lacks {', '.join(missing)} "
            "(a GeoPackage of another program, or of an incompatible version)"
        )
    return ds


@contextlib.contextmanager
def _busy_timeout() -> Iterator[None]:
    """GDAL's wait for a lock while it opens a GeoPackage (its own default: 5 s) set to BUSY_TIMEOUT_MS."""
    previous = gdal.GetThreadLocalConfigOption("SQLITE_BUSY_TIMEOUT", None)
    gdal.SetThreadLocalConfigOption("SQLITE_BUSY_TIMEOUT", str(BUSY_TIMEOUT_MS))
    try:
        yield
    finally:
        gdal.SetThreadLocalConfigOption("SQLITE_BUSY_TIMEOUT", previous)


def _open(path: str, update: bool) -> ogr.DataSource | None:
    """ogr.Open of the block, with its failures in Pushbroom's words (open_block)."""
    try:
        with _busy_timeout():
            try:
                return ogr.Open(path, 1 if update else 0)
            except RuntimeError as exc:
                # a writer killed mid-transaction leaves a hot journal, which only a writable connection rolls back
                if update or "readonly database" not in str(exc).lower() or not os.access(path, os.W_OK):
                    raise
                ogr.Open(path, 1).Destroy()
                return ogr.Open(path, 0)
    except RuntimeError as exc:
        text = str(exc).lower()
        if _is_locked(exc):
            raise locked_error(path, "", reading=True) from None
        if "malformed" in text or damage(path):
            raise damaged_error(path, str(exc)) from None
        if "not recognized" in text or "not a database" in text:
            raise _not_a_block(path, "not a GeoPackage") from None
        if "required geopackage tables" in text:
            raise _not_a_block(path, "an SQLite database, but not a GeoPackage") from None
        raise storage_error(exc, path, "the block", action=f"read the block {path}") from None


def _failed(exc: RuntimeError, block_path: str, what: str) -> StorageError | InputError:
    """StorageError for an OGR/SQLite failure while storing `what` in the block."""
    if _is_locked(exc):
        return locked_error(block_path, what)
    text = str(exc).lower()
    if any(key in text for key in ("readonly", "read-only", "unable to open", "permission")):
        denied = write_access_error(block_path, what)
        if denied is not None:
            return denied
    if "malformed" in text:
        return damaged_error(block_path, str(exc))
    return storage_error(exc, block_path, what, action=f"store {what} in the block {block_path}")


@contextlib.contextmanager
def transaction(
    block_path: str, what: str = "the edit", expect: Mapping[str, int] | None = None
) -> Iterator[ogr.DataSource]:
    """The block's data source (update mode) inside one SQLite transaction that already holds the write
    lock (taken first, waiting up to BUSY_TIMEOUT_MS, so a concurrent writer fails this one before anything
    is written), committed when the block ends, rolled back on any error. `expect`: {part: generation} read
    before a computation; the transaction is refused (StorageError, nothing written) if any changed since.
    OGR/SQLite failures become StorageError("cannot store <what> ..."); a block this user may not change is
    refused first (write_access_error). The data source is closed when the block ends: do not use it afterwards."""
    denied = write_access_error(block_path, what)
    if denied is not None:
        raise denied
    ds = open_block(block_path, update=True)
    failed = True
    try:
        try:
            ds.StartTransaction()
            _execute(ds, "UPDATE block_info SET value = value WHERE key = 'format_version'")
        except RuntimeError as exc:
            raise _failed(exc, block_path, what) from None
        try:
            if expect:
                _check_generations(ds, block_path, what, expect)
            yield ds
            ds.CommitTransaction()
            failed = False
        except BaseException as exc:
            with contextlib.suppress(RuntimeError):
                ds.RollbackTransaction()
            if isinstance(exc, RuntimeError):  # OGR/SQLite: locked, read-only, disk full
                raise _failed(exc, block_path, what) from exc
            raise
    finally:
        try:
            _close(ds, block_path, what)
        except StorageError:
            if not failed:  # a failure already on its way is the one to report
                raise


def _close(ds: ogr.DataSource, block_path: str, what: str) -> None:
    """Close `ds` now (OGR finishes deferred work, such as feature count triggers, on close)."""
    try:
        ds.Destroy()
    except RuntimeError as exc:
        raise _failed(exc, block_path, what) from None


def check_writable(block_path: str, what: str = "the results") -> None:
    """Fail now (StorageError) where the block cannot be written: locked by another program beyond
    BUSY_TIMEOUT_MS, a file or folder this user may not write (write_access_error), damaged. A long step calls it
    before it computes."""
    with transaction(block_path, what):
        pass


def _generation_values(info: Mapping[str, str]) -> dict[str, int]:
    return {part: int(info.get(f"generation_{part}", 0) or 0) for part in GENERATIONS}


def generations(block_path: str) -> dict[str, int]:
    """{part: generation} of the block now (module docstring)."""
    return _generation_values(read_info(block_path))


def _check_generations(ds: ogr.DataSource, block_path: str, what: str, expect: Mapping[str, int]) -> None:
    now = _generation_values({f["key"]: f["value"] for f in ds.GetLayerByName("block_info")})
    changed = [part.replace("_", " ") for part, value in expect.items() if now.get(part) != value]
    if changed:
        raise StorageError(
            f"cannot store {what} in {block_path}: the block's {' and '.join(changed)} changed while "
            "this step computed (an import, an edit in the measurement window or in QGIS, or another "
            "step), so its results belong to the old state; nothing was stored. Run it again"
        )


def bump(ds: ogr.DataSource, part: str) -> None:
    """Increment the generation of `part` in the open block `ds` (inside the caller's transaction)."""
    info = {f["key"]: f["value"] for f in ds.GetLayerByName("block_info")}
    write_info(ds, {f"generation_{part}": _generation_values(info)[part] + 1})


def control_point_triggers(ds: ogr.DataSource, layer: str, table: str) -> None:
    """Create (where missing) the triggers that bump generation_control_points on any change of the control
    points' names, roles, coordinates and sigmas (not of residual_px, which the adjustment writes) and of
    their image measurements, in the open block `ds`."""
    bump_sql = "UPDATE block_info SET value = CAST(value AS INTEGER) + 1 WHERE key = 'generation_control_points'"
    info = {f["key"] for f in ds.GetLayerByName("block_info")}
    if "generation_control_points" not in info:
        write_info(ds, {"generation_control_points": 0})
    columns = {
        layer: "name, role, lon, lat, h, sigma_e, sigma_n, sigma_h, geom",
        table: "point_name, image_id, col, row, sigma",
    }
    for name, cols in columns.items():
        for event in ("INSERT", "DELETE", f"UPDATE OF {cols}"):
            trigger = f"pushbroom_generation_{name}_{event.split()[0].lower()}"
            _execute(ds, f'CREATE TRIGGER IF NOT EXISTS "{trigger}" AFTER {event} ON "{name}" BEGIN {bump_sql}; END')


def read_info(path: str | os.PathLike[str]) -> dict[str, str]:
    """The block_info table as a dict."""
    ds = open_block(path)  # keep the data source alive while its layer is read
    return {feat["key"]: feat["value"] for feat in ds.GetLayerByName("block_info")}


def height_range(path: str | os.PathLike[str]) -> tuple[float, float] | None:
    """The terrain height range (min, max) recorded at the block's creation, or None."""
    info = read_info(path)
    try:
        return float(info["height_min"]), float(info["height_max"])
    except (KeyError, ValueError):
        return None


def write_info(ds: ogr.DataSource, values: Mapping[str, object], step: str | None = None, message: str = "") -> None:
    """update_info on an open block data source, inside the caller's transaction."""
    layer = ds.GetLayerByName("block_info")
    for key, value in values.items():
        layer.SetAttributeFilter(f"key = '{key}'")
        feat = layer.GetNextFeature()
        layer.SetAttributeFilter(None)
        if feat is None:
            feat = ogr.Feature(layer.GetLayerDefn())
            feat["key"], feat["value"] = key, str(value)
            layer.CreateFeature(feat)
        else:
            feat["value"] = str(value)
            layer.SetFeature(feat)
    if step is not None:
        log = ds.GetLayerByName("run_log")
        feat = ogr.Feature(log.GetLayerDefn())
        feat["time"] = datetime.datetime.now(datetime.timezone.utc).isoformat()
        feat["step"], feat["parameters"], feat["message"] = step, json.dumps(values), message
        log.CreateFeature(feat)


def update_info(path: str, values: Mapping[str, object], step: str | None = None, message: str = "") -> None:
    """Set block_info keys (a dict) and, with `step`, append a run_log row, in one transaction."""
    with transaction(path, "the block information") as ds:
        write_info(ds, values, step, message)


def read_run_log(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The run_log table (time, step, parameters, message) as a list of dicts, oldest first."""
    ds = open_block(path)
    return [
        {key: feat[key] for key in ("time", "step", "parameters", "message")} for feat in ds.GetLayerByName("run_log")
    ]
