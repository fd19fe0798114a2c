"""Sensor models behind one interface (see base.SensorModel) and `load`, which opens any
supported orientation source:

- a SPOT 1-5 DIMAP METADATA.DIM (or its product folder, or its IMAGERY.TIF),
- a raster with RPC metadata (GeoTIFF RPC tags, _RPC.TXT or .RPB beside it),
- an RPC file (_RPC.TXT, .RPB) or an OSSIM/OTB .geom keyword list,
- the project's own model file (*.pbmodel.json), as written by `save`.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from ..errors import InputError, MetadataError
from .base import SensorModel

if TYPE_CHECKING:
    from .rpc import RpcModel
    from .spot import SpotModel

MODEL_FILE_SUFFIX = ".pbmodel.json"


def _is_dimap(path: str | os.PathLike[str]) -> bool:
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError:
        return False
    return b"<Dimap_Document" in head


#: names of orientation files, which are their own source (never redirected to a neighbour)
ORIENTATION_SUFFIXES = (".dim", ".geom", ".rpb", "_rpc.txt", MODEL_FILE_SUFFIX)


def orientation_source(path: str | os.PathLike[str]) -> str:
    """The file holding the orientation of image (or folder) `path`: an orientation file itself;
    for a raster, an OSSIM .geom of the same stem, else a DIMAP METADATA.DIM in its folder, else the
    raster itself (GDAL reads RPCs from its tags or from an _RPC.TXT / .RPB beside it)."""
    path = os.fspath(path)
    if os.path.isdir(path):
        dim = os.path.join(path, "METADATA.DIM")
        if not os.path.exists(dim):
            raise MetadataError(f"folder {path} holds no METADATA.DIM (not a SPOT DIMAP product)")
        return dim
    if path.lower().endswith(ORIENTATION_SUFFIXES) or _is_dimap(path):
        return path
    geom = os.path.splitext(path)[0] + ".geom"
    if os.path.exists(geom):
        return geom
    sibling = os.path.join(os.path.dirname(path), "METADATA.DIM")
    if os.path.exists(sibling):
        return sibling
    return path


def missing_file_error(path: str) -> InputError:
    """InputError for `path`, which does not exist: the raster of a SPOT DIMAP product whose
    METADATA.DIM lies where the raster should be, or any other file."""
    folder = os.path.dirname(os.path.abspath(path))
    dim = os.path.join(folder, "METADATA.DIM")
    if not path.lower().endswith(ORIENTATION_SUFFIXES) and _is_dimap(dim):
        return InputError(
            f"{path} does not exist: the SPOT DIMAP product {folder} has its metadata {dim} but "
            "not this raster; copy the product's raster (as delivered: IMAGERY.TIF) back beside its "
            "METADATA.DIM, or give an image that exists"
        )
    return InputError(f"{path} does not exist: check the path (a file moved, renamed or deleted?)")


def check_image(path: str | os.PathLike[str]) -> None:
    """InputError unless the image `path` exists (missing_file_error) and, where it is a SPOT DIMAP
    METADATA.DIM or product folder, the product's raster (dimap.product_raster) exists beside it."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise missing_file_error(path)
    dim = os.path.join(path, "METADATA.DIM") if os.path.isdir(path) else path
    if _is_dimap(dim):
        from .dimap import product_raster

        raster = product_raster(dim)
        if not os.path.isfile(raster):
            raise InputError(
                f"{path} is a SPOT DIMAP product without its raster: {raster}, which its metadata "
                "names, does not exist; copy the product's raster back beside its METADATA.DIM, or "
                "give an image that exists"
            )


def load(path: str | os.PathLike[str], image: str | os.PathLike[str] | None = None) -> SpotModel | RpcModel:
    """Open the orientation at `path` and return its SensorModel (see module docstring).

    `image` is the raster the model describes when `path` is a separate orientation file: its size
    is checked against the metadata, and a crop offset (Pleiades .geom crops) is honoured. A missing
    `path` or `image` is an InputError naming it (missing_file_error)."""
    path = os.fspath(path)
    for given in (path, image):
        if given is not None and not os.path.exists(given):
            raise missing_file_error(os.fspath(given))
    if image is None and not path.lower().endswith(MODEL_FILE_SUFFIX):
        source = orientation_source(path)
        if source != path:
            image, path = (path if not os.path.isdir(path) else None), source
    lower = path.lower()
    if lower.endswith(MODEL_FILE_SUFFIX):
        from .model_file import load_model_file

        return load_model_file(path)
    if lower.endswith(".dim") or _is_dimap(path):
        from .spot import SpotModel

        return SpotModel.from_dimap(path, image=image)
    from .rpc import RpcModel

    if lower.endswith(".geom"):
        return RpcModel.from_geom(path, image=image)
    if lower.endswith((".rpb", "_rpc.txt")):
        return RpcModel.from_rpc_file(path)
    return RpcModel.from_raster(path)


def save(model: SensorModel, path: str | os.PathLike[str]) -> None:
    """Write `model` (with its corrections) to the project's own model file format."""
    from .model_file import save_model_file

    save_model_file(model, path)


__all__ = [
    "SensorModel",
    "load",
    "save",
    "orientation_source",
    "check_image",
    "missing_file_error",
    "MODEL_FILE_SUFFIX",
]
