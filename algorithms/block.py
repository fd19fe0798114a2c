"""The block store: one GeoPackage per block (DESIGN.md, "Data").

Tables: `block_info` (key/value: format version, creation time, default CRS, terrain height range,
references to the point files beside the block), `images` (one row per
image: name, raster path, orientation source, model kind, sensor, size, and the sensor model as
a model-file document, see sensors/model_file.py),
`footprints` (polygon layer, EPSG:4326, the image border projected on a DEM or a mean height) and
`run_log` (one row per processing step). A block is written under a temporary name and renamed,
so a failed or cancelled creation leaves any existing block untouched."""
import contextlib
import datetime
import json
import os

import numpy as np
from osgeo import ogr

from . import progress
from .atomic import atomic_path
from .crs import wgs84
from .errors import InputError, PushbroomError
from .geodesy import utm_epsg
from .sensors.model_file import model_from_dict, model_to_dict

FORMAT_VERSION = "1"
IMAGE_FIELDS = [("name", ogr.OFTString), ("image_path", ogr.OFTString),
                ("orientation_path", ogr.OFTString), ("model_kind", ogr.OFTString),
                ("sensor", ogr.OFTString), ("cols", ogr.OFTInteger), ("rows", ogr.OFTInteger),
                ("model", ogr.OFTString)]


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
        ds = create_schema(tmp)
        table, footprints = ds.GetLayerByName("images"), ds.GetLayerByName("footprints")
        for k, ((name, image, orientation, model), ring) in enumerate(zip(images, rings), start=1):
            kind, sensor = describe_model(model)
            feat = ogr.Feature(table.GetLayerDefn())
            feat.SetFID(k)
            cols, rows = model.size
            for key, value in [("name", name), ("image_path", os.path.abspath(image) if image else ""),
                               ("orientation_path", os.path.abspath(orientation)), ("model_kind", kind),
                               ("sensor", sensor), ("cols", int(cols)), ("rows", int(rows)),
                               ("model", json.dumps(model_to_dict(model)))]:
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
        ds = None
        update_info(tmp, {"created": datetime.datetime.now(datetime.timezone.utc).isoformat(),
                          "default_crs": f"EPSG:{utm_epsg(*centre)}",
                          "footprint_height": "dem" if dem is not None else repr(float(height)),
                          "height_min": repr(h_min), "height_max": repr(h_max)},
                    step="createblock", message=f"block created with {len(images)} image(s): {', '.join(names)}")
        progress.step(feedback, 100.0)
    return path


def create_schema(path):
    """A new, empty block GeoPackage at `path` (its tables, format version); returns the data source."""
    ogr.UseExceptions()
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(os.fspath(path))
    info = create_layer(ds, "block_info", ogr.wkbNone, None, [("key", ogr.OFTString), ("value", ogr.OFTString)])
    feat = ogr.Feature(info.GetLayerDefn())
    feat["key"], feat["value"] = "format_version", FORMAT_VERSION
    info.CreateFeature(feat)
    create_layer(ds, "images", ogr.wkbNone, None, IMAGE_FIELDS)
    create_layer(ds, "footprints", ogr.wkbPolygon, wgs84(), [("image_id", ogr.OFTInteger), ("name", ogr.OFTString)])
    create_layer(ds, "run_log", ogr.wkbNone, None, [("time", ogr.OFTString), ("step", ogr.OFTString),
                                                      ("parameters", ogr.OFTString), ("message", ogr.OFTString)])
    return ds


def read_images(path):
    """The images table of a block as a list of dicts (id, name, image_path, ...)."""
    if not os.path.exists(path):
        raise InputError(f"no block at {path}")
    ds = ogr.Open(os.fspath(path))
    layer = ds.GetLayerByName("images") if ds is not None else None
    if layer is None:
        raise InputError(f"{path} is not a Pushbroom block (no images table)")
    rows = []
    for feat in layer:
        row = {"id": feat.GetFID()}
        row.update({name: feat[name] for name, _ in IMAGE_FIELDS if name != "model"})
        rows.append(row)
    return rows


def load_model(path, image_id):
    """The sensor model stored in the block for image `image_id`."""
    ds = ogr.Open(os.fspath(path))
    layer = ds.GetLayerByName("images") if ds is not None else None
    feat = layer.GetFeature(int(image_id)) if layer is not None else None
    if feat is None:
        raise InputError(f"block {path} has no image with id {image_id}")
    return model_from_dict(json.loads(feat["model"]), f"model of image {image_id} in {path}")


def save_models(path, models, step="adjust", message=""):
    """Replace the stored sensor models of the images {image_id: model} and log the step, in one
    transaction (all or nothing)."""
    docs = {int(i): json.dumps(model_to_dict(m)) for i, m in models.items()}
    ds = open_block(path, update=True)
    layer = ds.GetLayerByName("images")
    ds.StartTransaction()
    try:
        for image_id, doc in docs.items():
            feat = layer.GetFeature(image_id)
            if feat is None:
                raise InputError(f"block {path} has no image with id {image_id}")
            feat["model"] = doc
            layer.SetFeature(feat)
        write_info(ds, {}, step=step, message=message or f"{len(docs)} sensor model(s) updated")
    except BaseException:
        ds.RollbackTransaction()
        raise
    ds.CommitTransaction()


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


def open_block(path, update=False):
    """The block's OGR data source; InputError if `path` is no Pushbroom block."""
    if not os.path.exists(os.fspath(path)):
        raise InputError(f"no block at {path}")
    ogr.UseExceptions()
    ds = ogr.Open(os.fspath(path), 1 if update else 0)
    if ds is None or ds.GetLayerByName("block_info") is None:
        raise InputError(f"{path} is not a Pushbroom block (no block_info table)")
    return ds


#: ms a transaction waits for another connection's write lock (QGIS editing the layer, an adjustment storing
#: its results) before it gives up with an error
BUSY_TIMEOUT_MS = 5000


@contextlib.contextmanager
def transaction(block_path, what="the edit"):
    """The block's data source (update mode) inside one SQLite transaction that already holds the
    write lock (taken first, so a concurrent writer is waited for up to BUSY_TIMEOUT_MS rather than
    failing the edit half-way), committed when the block ends, rolled back on any error; OGR/SQLite
    errors become InputError("cannot store <what> ...")."""
    ds = open_block(block_path, update=True)
    result = ds.ExecuteSQL(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
    if result is not None:
        ds.ReleaseResultSet(result)
    ds.StartTransaction()
    try:
        ds.ExecuteSQL("UPDATE block_info SET value = value WHERE key = 'format_version'")
        yield ds
        ds.CommitTransaction()
    except BaseException as exc:
        ds.RollbackTransaction()
        if isinstance(exc, RuntimeError):   # OGR/SQLite: locked, read-only, disk full
            raise InputError(f"cannot store {what} in {block_path}: {exc}") from exc
        raise


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
    ds = open_block(path, update=True)
    ds.StartTransaction()
    write_info(ds, values, step, message)
    ds.CommitTransaction()
