"""The project's own sensor-model file (*.pbmodel.json): a model, with its corrections, saved so
that `sensors.load` gives back the same model bit for bit (floats are written with repr, which
round-trips exactly). Adjusted models are stored this way.

{"format": "pushbroom-sensor-model", "version": 1, "kind": "spot" | "rpc", ...}
- spot: "drift" and "orientation" (every SpotOrientation field; arrays as nested lists, the epoch
  as an ISO string, "corrections" as a dict of the Corrections fields);
- rpc: "fields" (GDAL RPC metadata names, offsets already on the model's own raster), "size",
  "source", and "bias" (the adjustment's six image-space bias terms, rpc.py) where nonzero."""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ..atomic import write_text
from ..errors import MetadataError

if TYPE_CHECKING:
    from .base import SensorModel
    from .rpc import RpcModel
    from .spot import SpotModel
    from .spot_orientation import SpotOrientation

FORMAT = "pushbroom-sensor-model"
VERSION = 1


def _plain(value: object) -> object:
    """JSON-ready copy of a dataclass field value."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.datetime64):
        return str(np.datetime_as_string(value, unit="ns"))
    if dataclasses.is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.generic):
        return value.item()
    return value


def model_to_dict(model: SensorModel) -> dict[str, object]:
    """The model-file document of a SpotModel or RpcModel."""
    from .rpc import RpcModel
    from .spot import SpotModel

    if isinstance(model, SpotModel):
        return {
            "format": FORMAT,
            "version": VERSION,
            "kind": "spot",
            "drift": model.drift,
            "orientation": _plain(model.orientation),
        }
    if isinstance(model, RpcModel):
        doc: dict[str, object] = {
            "format": FORMAT,
            "version": VERSION,
            "kind": "rpc",
            "fields": model.to_fields(),
            "size": list(model.size),
            "source": model.source,
        }
        if model.bias.any():
            doc["bias"] = [float(v) for v in model.bias]
        return doc
    raise MetadataError(f"cannot save a model of type {type(model).__name__}")


def _orientation(doc: Mapping[str, Any]) -> SpotOrientation:
    from .spot_orientation import Corrections, SpotOrientation

    fields: dict[str, Any] = {k: np.asarray(v, dtype=np.float64) if isinstance(v, list) else v for k, v in doc.items()}
    fields["epoch"] = np.datetime64(fields["epoch"], "ns")
    corrections = dict(fields.get("corrections") or {})
    for name in ("position", "attitude", "look"):
        if name in corrections:
            corrections[name] = np.asarray(corrections[name], dtype=np.float64)
    fields["corrections"] = Corrections(**corrections)
    return SpotOrientation(**fields)


def model_from_dict(doc: object, source: str = "model file") -> SpotModel | RpcModel:
    """The SpotModel or RpcModel of a model-file document; MetadataError if it is not one."""
    from .rpc import RpcCoefficients, RpcModel
    from .spot import SpotModel

    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise MetadataError(f"{source} is not a Pushbroom sensor-model file")
    if doc.get("version") != VERSION:
        raise MetadataError(
            f"{source} has model-file version {doc.get('version')!r}; this Pushbroom "
            f"reads version {VERSION}: update the plugin"
        )
    try:
        if doc.get("kind") == "spot":
            return SpotModel(_orientation(doc["orientation"]), drift=bool(doc["drift"]))
        if doc.get("kind") == "rpc":
            coefficients = RpcCoefficients.from_fields(doc["fields"], source)
            size = tuple(int(v) for v in doc["size"])
            if len(size) != 2 or min(size) < 1:
                raise ValueError(f"size {doc['size']!r} is not (cols, rows) of a raster")
            bias = np.asarray(doc.get("bias", np.zeros(6)), float)
            if bias.shape != (6,) or not np.all(np.isfinite(bias)):
                raise ValueError(f"bias {doc.get('bias')!r} is not 6 finite numbers")
            return RpcModel(coefficients, size=size, source=doc.get("source", source), bias=bias)
    except MetadataError:
        raise
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise MetadataError(
            f"{source} is damaged ({type(exc).__name__}: {exc}); re-create it from the original metadata or the block"
        ) from exc
    raise MetadataError(f"{source}: unknown model kind {doc.get('kind')!r} (expected 'spot' or 'rpc')")


def save_model_file(model: SensorModel, path: str | os.PathLike[str]) -> None:
    """Write `model` to `path` atomically."""
    write_text(path, json.dumps(model_to_dict(model), indent=1))


def load_model_file(path: str | os.PathLike[str]) -> SpotModel | RpcModel:
    """Read a model written by save_model_file."""
    try:
        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MetadataError(f"cannot read sensor-model file {path}: {exc}") from exc
    return model_from_dict(doc, str(path))
