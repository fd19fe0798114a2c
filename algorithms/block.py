"""The block store: one GeoPackage per block (DESIGN.md, "Data").

Tables: `block_info` (key/value: format version, creation time, default CRS, terrain height range,
references to the point files beside the block), `images` (one row per
image: name, raster path, orientation source, model kind, sensor, size, and the sensor model as
a model-file document, see sensors/model_file.py),
`footprints` (polygon layer, EPSG:4326, the image border projected on a DEM or a mean height) and
`run_log` (one row per processing step). The images table also keeps each image's supplied model
(`supplied_model`, the orientation the block was created with), from which every bundle adjustment
starts, so that adjusting again gives the result of the first adjustment, not a correction of it. A block is written under a temporary name and renamed,
so a failed or cancelled creation leaves any existing block untouched.

Every later write is one SQLite transaction (`transaction`) that takes the write lock first, waiting up to
BUSY_TIMEOUT_MS for another writer (QGIS saving an edit, another step) and then failing with a message that
says what to do; nothing is half-stored. Every connection waits the same way for other connections' locks.

Generations. block_info holds a counter per part of the block a computation reads: `generation_<part>` for
GENERATIONS. A step that computes from the block for a long time (the bundle adjustment) reads them first
(`generations`) and stores its results only if they are unchanged (`transaction(..., expect=...)`), so a
result computed from a control set that an import or an edit replaced meanwhile is refused, not stored
beside the new set. The point files and the models bump theirs in their own transactions; the control
points' counter is bumped by SQLite triggers on the `control_points` layer and the `image_measurements`
table (`control_point_triggers`), so edits made in QGIS's own attribute table count too."""
import contextlib
import datetime
import json
import os

import numpy as np
from osgeo import ogr

from . import progress
from .atomic import atomic_path, closing, storage_error
from .crs import wgs84
from .errors import InputError, PushbroomError, StorageError
from .geodesy import utm_epsg
from .sensors.model_file import model_from_dict, model_to_dict

FORMAT_VERSION = "1"
IMAGE_FIELDS = [("name", ogr.OFTString), ("image_path", ogr.OFTString),
                ("orientation_path", ogr.OFTString), ("model_kind", ogr.OFTString),
                ("sensor", ogr.OFTString), ("cols", ogr.OFTInteger), ("rows", ogr.OFTInteger),
                ("model", ogr.OFTString)]
#: the images table's field of the supplied models (missing in blocks of format 1 made before it)
SUPPLIED = "supplied_model"


def describe_model(model):
    """(model kind, sensor description) of a sensor model, for the images table."""
    orientation = getattr(model, "orientation", None)
    if orientation is not None:
        sensor = f"SPOT {orientation.mission} {orientation.instrument}{orientation.instrument_index}"
        return "spot_dimap", sensor.strip()
    return "rpc", "RPC"


def create_layer(ds, name, geom_type, srs, fields):
    """A new layer (or table, geom_type wkbNone) with an integer fid and the given (name, OFT type) fields."""
    layer = ds.CreateLayer(name, srs, geom_type, options=["FID=fid"])
    for field_name, field_type in fields:
        layer.CreateField(ogr.FieldDefn(field_name, field_type))
    return layer


#: half width (m) of the terrain height range recorded for a block made at a mean height
HEIGHT_MARGIN = 500.0


def terrain_height_range(rings, height, dem):
    """(min, max) ellipsoidal terrain height of the block: the DEM's valid heights inside the
    footprints' bounding box, or the mean height +- HEIGHT_MARGIN."""
    if dem is None:
        return float(height) - HEIGHT_MARGIN, float(height) + HEIGHT_MARGIN
    allpts = np.vstack(rings)
    lon0, dlon, _, lat0, _, dlat = dem.geotransform
    cols = np.clip(((allpts[:, 0] - lon0) / dlon).astype(int), 0, dem.shape[1] - 1)
    rows = np.clip(((allpts[:, 1] - lat0) / dlat).astype(int), 0, dem.shape[0] - 1)
    window = dem.heights[rows.min():rows.max() + 1, cols.min():cols.max() + 1]
    return float(np.nanmin(window)), float(np.nanmax(window))


def create_block(path, images, height=0.0, dem=None, overwrite=False, feedback=None):
    """Create `path` (a .gpkg) from `images`, a list of (name, image_path, orientation_path, model).

    Footprints are the image borders on `dem` (algorithms.dem.Dem) or at ellipsoidal `height`.
    Refuses to replace an existing block unless `overwrite` is true."""
    path = os.fspath(path)
    if not path.lower().endswith(".gpkg"):
        raise InputError(f"a block is a GeoPackage: give a path ending in .gpkg, not {path}")
    if os.path.exists(path) and not overwrite:
        raise InputError(f"block {path} exists already; set the overwrite parameter to replace it")
    if not images:
        raise InputError("a block needs at least one image")
    names = [name for name, *_ in images]
    if len(set(names)) != len(names):
        raise InputError(f"image names must be unique in a block, got {names}")
    rings = []
    for k, (name, _image, _orientation, model) in enumerate(images):
        progress.step(feedback, 90.0 * k / len(images), f"footprint of {name}")
        try:
            rings.append(model.footprint(h=height, dem=dem))
        except PushbroomError as exc:
            raise InputError(f"cannot project the footprint of image {name}: {exc}") from exc
    centre = sum(r[:-1].mean(axis=0) for r in rings) / len(rings)
    h_min, h_max = terrain_height_range(rings, height, dem)
    with atomic_path(path) as tmp:
        with closing(create_schema(tmp)) as ds:
            _write_images(ds, images, rings)
        update_info(tmp, {"created": datetime.datetime.now(datetime.timezone.utc).isoformat(),
                          "default_crs": f"EPSG:{utm_epsg(*centre)}",
                          "footprint_height": "dem" if dem is not None else repr(float(height)),
                          "height_min": repr(h_min), "height_max": repr(h_max)},
                    step="createblock", message=f"block created with {len(images)} image(s): {', '.join(names)}")
        progress.step(feedback, 100.0)
    return path


def _write_images(ds, images, rings):
    """The images table and the footprints layer of a new block `ds`."""
    table, footprints = ds.GetLayerByName("images"), ds.GetLayerByName("footprints")
    for k, ((name, image, orientation, model), ring) in enumerate(zip(images, rings), start=1):
        kind, sensor = describe_model(model)
        feat = ogr.Feature(table.GetLayerDefn())
        feat.SetFID(k)
        cols, rows = model.size
        for key, value in [("name", name), ("image_path", os.path.abspath(image) if image else ""),
                           ("orientation_path", os.path.abspath(orientation)), ("model_kind", kind),
                           ("sensor", sensor), ("cols", int(cols)), ("rows", int(rows)),
                           ("model", json.dumps(model_to_dict(model))),
                           (SUPPLIED, json.dumps(model_to_dict(model)))]:
            feat[key] = value
        table.CreateFeature(feat)
        poly = ogr.Geometry(ogr.wkbPolygon)
        lr = ogr.Geometry(ogr.wkbLinearRing)
        for lon, lat in ring:
            lr.AddPoint_2D(float(lon), float(lat))
        poly.AddGeometry(lr)
        feat = ogr.Feature(footprints.GetLayerDefn())
        feat.SetFID(k)
        feat["image_id"], feat["name"] = k, name
        feat.SetGeometry(poly)
        footprints.CreateFeature(feat)


def create_schema(path):
    """A new, empty block GeoPackage at `path` (its tables, format version); returns the data source."""
    ogr.UseExceptions()
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(os.fspath(path))
    info = create_layer(ds, "block_info", ogr.wkbNone, None, [("key", ogr.OFTString), ("value", ogr.OFTString)])
    feat = ogr.Feature(info.GetLayerDefn())
    feat["key"], feat["value"] = "format_version", FORMAT_VERSION
    info.CreateFeature(feat)
    create_layer(ds, "images", ogr.wkbNone, None, IMAGE_FIELDS + [(SUPPLIED, ogr.OFTString)])
    create_layer(ds, "footprints", ogr.wkbPolygon, wgs84(), [("image_id", ogr.OFTInteger), ("name", ogr.OFTString)])
    create_layer(ds, "run_log", ogr.wkbNone, None, [("time", ogr.OFTString), ("step", ogr.OFTString),
                                                      ("parameters", ogr.OFTString), ("message", ogr.OFTString)])
    return ds


def read_images(path):
    """The images table of a block as a list of dicts (id, name, image_path, ...)."""
    ds = open_block(path)
    rows = []
    for feat in ds.GetLayerByName("images"):
        row = {"id": feat.GetFID()}
        row.update({name: feat[name] for name, _ in IMAGE_FIELDS if name != "model"})
        rows.append(row)
    return rows


def load_model(path, image_id, supplied=False):
    """The sensor model stored in the block for image `image_id`; with `supplied`, the model the block was
    created with (module docstring; the stored one in blocks made before the block kept it)."""
    ds = open_block(path)
    layer = ds.GetLayerByName("images")
    feat = layer.GetFeature(int(image_id))
    if feat is None:
        raise InputError(f"block {path} has no image with id {image_id}")
    key = "model"
    if supplied and layer.GetLayerDefn().GetFieldIndex(SUPPLIED) >= 0 and feat[SUPPLIED]:
        key = SUPPLIED
    return model_from_dict(json.loads(feat[key]), f"{key.replace('_', ' ')} of image {image_id} in {path}")


def write_models(ds, models, step="adjust", message="", supplied=False):
    """Replace the stored sensor models of the images {image_id: model} of the open block `ds` (with
    `supplied`, the supplied models too: a new supplied orientation) and log the step, inside the caller's
    transaction; bumps generation_models."""
    layer = ds.GetLayerByName("images")
    if supplied and layer.GetLayerDefn().GetFieldIndex(SUPPLIED) < 0:
        layer.CreateField(ogr.FieldDefn(SUPPLIED, ogr.OFTString))
    for image_id, model in models.items():
        feat = layer.GetFeature(int(image_id))
        if feat is None:
            raise InputError(f"the block has no image with id {image_id}")
        feat["model"] = json.dumps(model_to_dict(model))
        if supplied:
            feat[SUPPLIED] = feat["model"]
        layer.SetFeature(feat)
    bump(ds, "models")
    write_info(ds, {}, step=step, message=message or f"{len(models)} sensor model(s) updated")


def save_models(path, models, step="adjust", message="", supplied=False):
    """`write_models` in one transaction (all or nothing)."""
    with transaction(path, "the sensor models") as ds:
        write_models(ds, models, step, message, supplied)


def image_name(image_path):
    """A readable image name: the product folder for DIMAP (…/HRS1/IMAGERY.TIF -> HRS1), else the stem."""
    stem = os.path.splitext(os.path.basename(image_path))[0]
    if stem.upper() == "IMAGERY" or os.path.basename(image_path).upper() == "METADATA.DIM":
        return os.path.basename(os.path.dirname(os.path.abspath(image_path))) or stem
    return stem


def open_images(image_paths, orientation_paths=None):
    """(name, image path, orientation path, model) per image; orientation found beside the image
    unless given (same order)."""
    from . import sensors
    orientation_paths = list(orientation_paths or [])
    if orientation_paths and len(orientation_paths) != len(image_paths):
        raise InputError(f"{len(orientation_paths)} orientation files for {len(image_paths)} images: "
                         "give one per image, in the same order, or none")
    result, seen = [], set()
    for k, image in enumerate(image_paths):
        orientation = orientation_paths[k] if orientation_paths else sensors.orientation_source(image)
        model = sensors.load(orientation, image=image)
        name = image_name(image)
        unique, n = name, 2
        while unique in seen:
            unique, n = f"{name}_{n}", n + 1
        seen.add(unique)
        result.append((unique, image, orientation, model))
    return result


#: ms a connection waits for another connection's lock (QGIS saving an edit of one of the block's layers, a step
#: storing its results) before it gives up with a StorageError
BUSY_TIMEOUT_MS = 10000
#: the parts of a block whose changes a long computation must not miss (module docstring)
GENERATIONS = ("control_points", "tie_points", "mass_points", "models")


def _execute(ds, sql):
    result = ds.ExecuteSQL(sql)
    if result is not None:
        ds.ReleaseResultSet(result)


def locked_error(block_path, what):
    """StorageError for a block another connection keeps locked beyond BUSY_TIMEOUT_MS."""
    return StorageError(f"cannot store {what} in the block {block_path}: another program keeps it locked (waited "
                        f"{BUSY_TIMEOUT_MS / 1000:g} s). Save or stop the edits of its layers in QGIS, or wait for the "
                        "other Pushbroom step to finish, then run this one again; nothing was stored")


def _is_locked(exc):
    text = str(exc).lower()
    return "locked" in text or "busy" in text


def open_block(path, update=False):
    """The block's OGR data source, waiting up to BUSY_TIMEOUT_MS for other connections' locks; InputError
    if `path` is no Pushbroom block (no file, not a GeoPackage, or a GeoPackage of another program),
    StorageError if it cannot be opened (damaged, no permission)."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"no block at {path}")
    ogr.UseExceptions()
    try:
        try:
            ds = ogr.Open(path, 1 if update else 0)
        except RuntimeError as exc:
            # a writer killed mid-transaction leaves a hot journal, which only a writable connection rolls back
            if update or "readonly database" not in str(exc).lower() or not os.access(path, os.W_OK):
                raise
            ogr.Open(path, 1).Destroy()
            ds = ogr.Open(path, 0)
    except RuntimeError as exc:
        text = str(exc).lower()
        if "not recognized" in text or "not a database" in text:
            raise InputError(f"{path} is not a Pushbroom block (not a GeoPackage): give the .gpkg that "
                             "pushbroom:createblock made") from None
        raise storage_error(exc, path, "the block") from None
    if ds is None or ds.GetLayerByName("block_info") is None:
        raise InputError(f"{path} is not a Pushbroom block (a GeoPackage without Pushbroom's block_info table, "
                         "perhaps made by another program): give the .gpkg that pushbroom:createblock made")
    _execute(ds, f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    images = ds.GetLayerByName("images")
    defn = images.GetLayerDefn() if images is not None else None
    fields = {defn.GetFieldDefn(k).GetName() for k in range(defn.GetFieldCount())} if defn is not None else set()
    missing = [name for name, _ in IMAGE_FIELDS if name not in fields]
    if missing:
        raise InputError(f"{path} is not a Pushbroom block: its images table lacks {', '.join(missing)} "
                         "(a GeoPackage of another program, or of an incompatible version)")
    return ds


def _failed(exc, block_path, what):
    """StorageError for an OGR/SQLite failure while storing `what` in the block."""
    if _is_locked(exc):
        return locked_error(block_path, what)
    return storage_error(exc, block_path, what, action=f"store {what} in the block {block_path}")


@contextlib.contextmanager
def transaction(block_path, what="the edit", expect=None):
    """The block's data source (update mode) inside one SQLite transaction that already holds the write
    lock (taken first, waiting up to BUSY_TIMEOUT_MS, so a concurrent writer fails this one before anything
    is written), committed when the block ends, rolled back on any error. `expect`: {part: generation} read
    before a computation; the transaction is refused (StorageError, nothing written) if any changed since.
    OGR/SQLite failures become StorageError("cannot store <what> ..."). The data source is closed when the
    block ends: do not use it afterwards."""
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
            if isinstance(exc, RuntimeError):   # OGR/SQLite: locked, read-only, disk full
                raise _failed(exc, block_path, what) from exc
            raise
    finally:
        try:
            _close(ds, block_path, what)
        except StorageError:
            if not failed:      # a failure already on its way is the one to report
                raise


def _close(ds, block_path, what):
    """Close `ds` now (OGR finishes deferred work, such as feature count triggers, on close)."""
    try:
        ds.Destroy()
    except RuntimeError as exc:
        raise _failed(exc, block_path, what) from None


def check_writable(block_path, what="the results"):
    """Fail now (StorageError) where the block cannot be written: locked by another program beyond
    BUSY_TIMEOUT_MS, read-only, damaged. A long step calls it before it computes."""
    with transaction(block_path, what):
        pass


def _generation_values(info):
    return {part: int(info.get(f"generation_{part}", 0) or 0) for part in GENERATIONS}


def generations(block_path):
    """{part: generation} of the block now (module docstring)."""
    return _generation_values(read_info(block_path))


def _check_generations(ds, block_path, what, expect):
    now = _generation_values({f["key"]: f["value"] for f in ds.GetLayerByName("block_info")})
    changed = [part.replace("_", " ") for part, value in expect.items() if now.get(part) != value]
    if changed:
        raise StorageError(f"cannot store {what} in {block_path}: the block's {' and '.join(changed)} changed while "
                           "this step computed (an import, an edit in the measurement window or in QGIS, or another "
                           "step), so its results belong to the old state; nothing was stored. Run it again")


def bump(ds, part):
    """Increment the generation of `part` in the open block `ds` (inside the caller's transaction)."""
    info = {f["key"]: f["value"] for f in ds.GetLayerByName("block_info")}
    write_info(ds, {f"generation_{part}": _generation_values(info)[part] + 1})


def control_point_triggers(ds, layer, table):
    """Create (where missing) the triggers that bump generation_control_points on any change of the control
    points' names, roles, coordinates and sigmas (not of residual_px, which the adjustment writes) and of
    their image measurements, in the open block `ds`."""
    bump_sql = "UPDATE block_info SET value = CAST(value AS INTEGER) + 1 WHERE key = 'generation_control_points'"
    info = {f["key"] for f in ds.GetLayerByName("block_info")}
    if "generation_control_points" not in info:
        write_info(ds, {"generation_control_points": 0})
    columns = {layer: "name, role, lon, lat, h, sigma_e, sigma_n, sigma_h, geom",
               table: "point_name, image_id, col, row, sigma"}
    for name, cols in columns.items():
        for event in ("INSERT", "DELETE", f"UPDATE OF {cols}"):
            trigger = f"pushbroom_generation_{name}_{event.split()[0].lower()}"
            _execute(ds, f'CREATE TRIGGER IF NOT EXISTS "{trigger}" AFTER {event} ON "{name}" BEGIN {bump_sql}; END')


def read_info(path):
    """The block_info table as a dict."""
    ds = open_block(path)  # keep the data source alive while its layer is read
    return {feat["key"]: feat["value"] for feat in ds.GetLayerByName("block_info")}


def height_range(path):
    """The terrain height range (min, max) recorded at the block's creation, or None."""
    info = read_info(path)
    try:
        return float(info["height_min"]), float(info["height_max"])
    except (KeyError, ValueError):
        return None


def write_info(ds, values, step=None, message=""):
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


def update_info(path, values, step=None, message=""):
    """Set block_info keys (a dict) and, with `step`, append a run_log row, in one transaction."""
    with transaction(path, "the block information") as ds:
        write_info(ds, values, step, message)
