"""The block's images: its creation, the images table and the sensor models.

The `images` table has one row per image: name, raster path, orientation source, model kind, sensor, size,
and the sensor model as a model-file document (sensors/model_file.py). It also keeps each image's supplied
model (`supplied_model`, the orientation the block was created with), from which every bundle adjustment
starts, so that adjusting again gives the result of the first adjustment, not a correction of it. The
`footprints` layer holds the image borders projected on a DEM or a mean height. A block is written under
a temporary name and renamed, so a failed or cancelled creation leaves any existing block untouched."""

from __future__ import annotations

import datetime
import json
import os
from collections.abc import Hashable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from osgeo import ogr

from .. import progress
from ..atomic import atomic_path, closing
from ..errors import InputError, PushbroomError
from ..file_identity import FileIdentity
from ..geodesy import utm_epsg
from ..progress import Feedback
from ..sensors.base import SensorModel
from ..sensors.model_file import model_from_dict, model_to_dict
from .schema import IMAGE_FIELDS, SUPPLIED, bump, create_schema, open_block, transaction, update_info, write_info

if TYPE_CHECKING:
    from ..dem_store import StoredDem

#: one image of a new block: (name, image path, orientation path, sensor model), as `open_images` gives it
ImageEntry = tuple[str, str, str, SensorModel]


def describe_model(model: SensorModel) -> tuple[str, str]:
    """(model kind, sensor description) of a sensor model, for the images table."""
    orientation = getattr(model, "orientation", None)
    if orientation is not None:
        sensor = f"SPOT {orientation.mission} {orientation.instrument}{orientation.instrument_index}"
        return "spot_dimap", sensor.strip()
    return "rpc", "RPC"


#: half width (m) of the terrain height range recorded for a block made at a mean height
HEIGHT_MARGIN = 500.0


def terrain_height_range(rings: Sequence[np.ndarray], height: float, dem: StoredDem | None) -> tuple[float, float]:
    """(min, max) ellipsoidal terrain height of the block: the valid heights of `dem` (dem_store.StoredDem)
    inside the footprints' bounding box, or the mean height +- HEIGHT_MARGIN."""
    if dem is None:
        return float(height) - HEIGHT_MARGIN, float(height) + HEIGHT_MARGIN
    allpts = np.vstack(rings)
    lon0, dlon, _, lat0, _, dlat = dem.geotransform
    cols = np.clip(((allpts[:, 0] - lon0) / dlon).astype(int), 0, dem.shape[1] - 1)
    rows = np.clip(((allpts[:, 1] - lat0) / dlat).astype(int), 0, dem.shape[0] - 1)
    return dem.cells_range((rows.min(), rows.max() + 1), (cols.min(), cols.max() + 1))


def check_new_block(path: str | os.PathLike[str], overwrite: bool) -> None:
    """Raise InputError where `path` cannot take a new block: not a .gpkg, or an existing file without
    `overwrite` (checked before any work, and again when the block is written)."""
    path = os.fspath(path)
    if not path.lower().endswith(".gpkg"):
        raise InputError(f"a block is a GeoPackage: give a path ending in .gpkg, not {path}")
    if os.path.exists(path) and not overwrite:
        raise InputError(f"block {path} exists already; set the overwrite parameter to replace it")


def create_block(
    path: str | os.PathLike[str],
    images: Sequence[ImageEntry],
    height: float | None = 0.0,
    dem: StoredDem | None = None,
    overwrite: bool = False,
    feedback: Feedback | None = None,
    height_range: tuple[float, float] | None = None,
) -> str:
    """Create `path` (a .gpkg) from `images`, a list of (name, image_path, orientation_path, model).

    Footprints are the image borders on `dem` (dem_store.StoredDem) or at ellipsoidal `height` (None, or
    ignored, with a `dem`); the terrain height range recorded is `height_range` where given (found by
    matching), else terrain_height_range's. Refuses to replace an existing block unless `overwrite` is true."""
    path = os.fspath(path)
    check_new_block(path, overwrite)
    if not images:
        raise InputError("a block needs at least one image")
    names = [name for name, *_ in images]
    if len(set(names)) != len(names):
        raise InputError(f"image names must be unique in a block, got {names}")
    if dem is None and height is None:
        raise InputError("a block's footprints need a DEM or a mean terrain height: give one of them")
    level = 0.0 if height is None else float(height)  # with a DEM, the footprints and height range ignore it
    rings: list[np.ndarray] = []
    for k, (name, _image, _orientation, model) in enumerate(images):
        progress.step(feedback, 90.0 * k / len(images), f"footprint of {name}")
        try:
            rings.append(model.footprint(h=level, dem=dem))
        except PushbroomError as exc:
            raise InputError(f"cannot project the footprint of image {name}: {exc}") from exc
    centre = sum(r[:-1].mean(axis=0) for r in rings) / len(rings)
    h_min, h_max = terrain_height_range(rings, level, dem) if height_range is None else height_range
    with atomic_path(path) as tmp:
        with closing(create_schema(tmp)) as ds:
            _write_images(ds, images, rings)
        update_info(
            tmp,
            {
                "created": datetime.datetime.now(datetime.timezone.utc).isoformat(),
                "default_crs": f"EPSG:{utm_epsg(*centre)}",
                "footprint_height": "dem" if dem is not None else repr(level),
                "height_min": repr(h_min),
                "height_max": repr(h_max),
            },
            step="createblock",
            message=f"block created with {len(images)} image(s): {', '.join(names)}",
        )
        progress.step(feedback, 100.0)
    return path


def _write_images(ds: ogr.DataSource, images: Sequence[ImageEntry], rings: Sequence[np.ndarray]) -> None:
    """The images table and the footprints layer of a new block `ds`."""
    table, footprints = ds.GetLayerByName("images"), ds.GetLayerByName("footprints")
    for k, ((name, image, orientation, model), ring) in enumerate(zip(images, rings), start=1):
        kind, sensor = describe_model(model)
        feat = ogr.Feature(table.GetLayerDefn())
        feat.SetFID(k)
        cols, rows = model.size
        for key, value in [
            ("name", name),
            ("image_path", os.path.abspath(image) if image else ""),
            ("orientation_path", os.path.abspath(orientation)),
            ("model_kind", kind),
            ("sensor", sensor),
            ("cols", int(cols)),
            ("rows", int(rows)),
            ("model", json.dumps(model_to_dict(model))),
            (SUPPLIED, json.dumps(model_to_dict(model))),
        ]:
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


def read_images(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The images table of a block as a list of dicts (id, name, image_path, ...)."""
    ds = open_block(path)
    rows = []
    for feat in ds.GetLayerByName("images"):
        row = {"id": feat.GetFID()}
        row.update({name: feat[name] for name, _ in IMAGE_FIELDS if name != "model"})
        rows.append(row)
    return rows


def image_ids(path: str | os.PathLike[str]) -> dict[str, int]:
    """{image name: image id} of the block's images, in block order."""
    return {r["name"]: r["id"] for r in read_images(path)}


def load_models(
    path: str | os.PathLike[str], image_ids: Iterable[int] | None = None, supplied: bool = False
) -> dict[int, SensorModel]:
    """{image id: sensor model} stored in the block for `image_ids` (default: every image, in block order),
    read in one pass; with `supplied`, the models the block was created with (module docstring; the
    stored ones in blocks made before the block kept them)."""
    ds = open_block(path)
    layer = ds.GetLayerByName("images")
    keeps_supplied = layer.GetLayerDefn().GetFieldIndex(SUPPLIED) >= 0
    if image_ids is None:
        image_ids = [feat.GetFID() for feat in layer]
    models: dict[int, SensorModel] = {}
    for image_id in image_ids:
        feat = layer.GetFeature(int(image_id))
        if feat is None:
            raise InputError(f"block {path} has no image with id {image_id}")
        key = SUPPLIED if supplied and keeps_supplied and feat[SUPPLIED] else "model"
        models[image_id] = model_from_dict(
            json.loads(feat[key]), f"{key.replace('_', ' ')} of image {image_id} in {path}"
        )
    return models


def write_models(
    ds: ogr.DataSource,
    models: Mapping[int, SensorModel],
    step: str = "adjust",
    message: str = "",
    supplied: bool = False,
) -> None:
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


def save_models(
    path: str, models: Mapping[int, SensorModel], step: str = "adjust", message: str = "", supplied: bool = False
) -> None:
    """`write_models` in one transaction (all or nothing)."""
    with transaction(path, "the sensor models") as ds:
        write_models(ds, models, step, message, supplied)


def image_name(image_path: str) -> str:
    """A readable image name: the product folder for DIMAP (…/HRS1/IMAGERY.TIF -> HRS1), else the stem."""
    stem = os.path.splitext(os.path.basename(image_path))[0]
    if stem.upper() == "IMAGERY" or os.path.basename(image_path).upper() == "METADATA.DIM":
        return os.path.basename(os.path.dirname(os.path.abspath(image_path))) or stem
    return stem


def check_distinct(paths: Sequence[str], what: str, why: str) -> None:
    """InputError where two of `paths` are one file (the same path twice, or one file through a link or another
    path): `what` names the list ("images"), `why` says why that is wrong."""
    first: dict[Hashable, int] = {}
    for k, path in enumerate(paths):
        key = FileIdentity.of(path).key
        if key in first:
            j = first[key]
            same = "the same path" if os.path.abspath(paths[j]) == os.path.abspath(path) else "one file"
            raise InputError(f"{what} {j + 1} and {k + 1} ({paths[j]} and {path}) are {same}: {why}; remove one")
        first[key] = k


def open_images(
    image_paths: Iterable[str | os.PathLike[str]], orientation_paths: Iterable[str | os.PathLike[str]] | None = None
) -> list[ImageEntry]:
    """(name, image path, orientation path, model) per image; orientation found beside the image
    unless given (same order). InputError where an image, or an orientation, comes twice (check_distinct:
    a DIMAP product given by its folder and by its raster has one METADATA.DIM)."""
    from .. import sensors

    images = [os.fspath(p) for p in image_paths]
    orientations = [os.fspath(p) for p in orientation_paths or []]
    if orientations and len(orientations) != len(images):
        raise InputError(
            f"{len(orientations)} orientation files for {len(images)} images: "
            "give one per image, in the same order, or none"
        )
    check_distinct(
        images,
        "images",
        "a block holds each image once (an image matched with itself gives points without parallax)",
    )
    orientations = orientations or [sensors.orientation_source(image) for image in images]
    check_distinct(
        orientations,
        "the orientations of images",
        "each image has an orientation of its own (one image given twice, or a wrong orientation file)",
    )
    result: list[ImageEntry] = []
    seen: set[str] = set()
    for image, orientation in zip(images, orientations):
        model = sensors.load(orientation, image=image)
        name = image_name(image)
        unique, n = name, 2
        while unique in seen:
            unique, n = f"{name}_{n}", n + 1
        seen.add(unique)
        result.append((unique, image, orientation, model))
    return result


def read_footprints(path: str | os.PathLike[str]) -> list[tuple[str, str]]:
    """[(name, WKT polygon)] of the block's image footprints (EPSG:4326)."""
    ds = open_block(path)
    layer = ds.GetLayerByName("footprints")
    return [(feat["name"], feat.GetGeometryRef().ExportToWkt()) for feat in layer] if layer is not None else []
