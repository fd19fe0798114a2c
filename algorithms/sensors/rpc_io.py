"""RPC00B files: reading GDAL rasters (metadata domain 'RPC'), _RPC.TXT, .RPB and OSSIM/OTB .geom
keyword lists into RpcRecords (RPC00B-named fields as texts, the raster size and crop offset), and
writing _RPC.TXT / .RPB files that GDAL reads back beside a raster. Number parsing and checking
is RpcCoefficients.from_fields's job (rpc.py)."""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, NamedTuple

from ..atomic import write_text
from ..errors import InputError, MetadataError

if TYPE_CHECKING:
    from osgeo import gdal

    from .rpc import RpcModel

#: a path as the readers and writers take it
Path = str | os.PathLike[str]

IMAGE_EXTENSIONS = (".tif", ".tiff", ".jp2", ".ntf", ".img", ".vrt")

#: RPC00B (GDAL metadata) names; OSSIM .geom uses them in lower case
OFFSET_KEYS = ("LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF")
SCALE_KEYS = ("LINE_SCALE", "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE")
COEFF_KEYS = ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF")
_SCALARS = OFFSET_KEYS + SCALE_KEYS

#: .RPB names of the RPC00B values
_RPB_NAMES = {
    "lineOffset": "LINE_OFF",
    "sampOffset": "SAMP_OFF",
    "latOffset": "LAT_OFF",
    "longOffset": "LONG_OFF",
    "heightOffset": "HEIGHT_OFF",
    "lineScale": "LINE_SCALE",
    "sampScale": "SAMP_SCALE",
    "latScale": "LAT_SCALE",
    "longScale": "LONG_SCALE",
    "heightScale": "HEIGHT_SCALE",
    "lineNumCoef": "LINE_NUM_COEFF",
    "lineDenCoef": "LINE_DEN_COEFF",
    "sampNumCoef": "SAMP_NUM_COEFF",
    "sampDenCoef": "SAMP_DEN_COEFF",
}

#: OSSIM polynomial_format A (RPC00A) term k is RPC00B term _A_TO_B[k]; A's order is
#: 1 L P H LP LH PH LPH L^2 P^2 H^2 L^3 L^2P L^2H LP^2 P^3 P^2H LH^2 PH^2 H^3 (ossimRpcModel)
_A_TO_B = (0, 1, 2, 3, 4, 5, 6, 10, 7, 8, 9, 11, 14, 17, 12, 15, 18, 13, 16, 19)


class RpcRecord(NamedTuple):
    """What a reader found: RPC00B fields (texts), (cols, rows) or None, crop offset, file name."""

    fields: Mapping[str, str | list[str]]
    size: tuple[int, int] | None
    offset: tuple[float, float]
    source: str


def _error(path: Path, what: str) -> MetadataError:
    return MetadataError(f"{path}: {what}")


def _read_text(path: str) -> str:
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return f.read()
    except OSError as exc:
        raise _error(path, f"cannot read the RPC file ({exc.strerror})") from exc


def _open_raster(path: Path) -> gdal.Dataset:
    from osgeo import gdal

    gdal.UseExceptions()
    try:
        return gdal.Open(os.fspath(path))
    except RuntimeError as exc:
        raise _error(path, f"GDAL cannot open it as a raster ({exc})") from exc


def _raster_size(ds: gdal.Dataset) -> tuple[int, int]:
    return ds.RasterXSize, ds.RasterYSize


def _sibling_image(stem: str) -> str | None:
    """The raster `stem` + one of IMAGE_EXTENSIONS (either case) that exists, or None."""
    for ext in IMAGE_EXTENSIONS:
        for candidate in (stem + ext, stem + ext.upper()):
            if os.path.isfile(candidate):
                return candidate
    return None


def _crop_offset(ds: gdal.Dataset, path: str) -> tuple[float, float]:
    """(col0, row0) of a raster cut from a sensor image: its geotransform must be a pure pixel
    translation (origin (col0, row0), pixel size (1, 1), no CRS), as OTB writes for an extract
    (OTB's origin is the first pixel's centre, GDAL's geotransform its corner); none means (0, 0)."""
    gt = ds.GetGeoTransform(can_return_null=True)
    if gt is None:
        return 0.0, 0.0
    if ds.GetSpatialRef() is None and tuple(gt[1:3]) == (1.0, 0.0) and tuple(gt[4:6]) == (0.0, 1.0):
        return float(gt[0]), float(gt[3])
    raise _error(
        path,
        f"its geotransform {tuple(gt)} is not a pixel offset into the sensor image, "
        "so the crop offset for the .geom's RPC is unknown; use the raster the RPC "
        "was delivered with, or a crop written by OTB/GDAL without georeferencing",
    )


def rpc_sidecar(ds: gdal.Dataset) -> str | None:
    """The _RPC.TXT or .RPB beside the raster of the open GDAL dataset `ds` that GDAL reads its RPC from (these
    come before the raster's own metadata), or None."""
    return next((f for f in ds.GetFileList() or [] if f.lower().endswith(("_rpc.txt", ".rpb"))), None)


def read_raster(path: Path) -> RpcRecord:
    """RPC of a raster as GDAL reads it (a same-stem .geom beside it is chosen earlier, by
    sensors.orientation_source); its source names the _RPC.TXT or .RPB GDAL read it from, where it did."""
    path = os.fspath(path)
    ds = _open_raster(path)
    fields = ds.GetMetadata("RPC") or {}
    if fields:
        beside = rpc_sidecar(ds)
        source = f"{path} (its RPC in {beside})" if beside else path
        return RpcRecord(fields, _raster_size(ds), (0.0, 0.0), source)
    raise _error(
        path,
        "the raster carries no RPC (GDAL finds none in its metadata, GeoTIFF RPC "
        "tags, or in a _RPC.TXT / .RPB beside it) and no .geom of the same name "
        "lies beside it; put the image's RPC file beside it or load the RPC file",
    )


def read_rpc_file(path: Path) -> RpcRecord:
    """RPC of a _RPC.TXT (KEY: value, coefficients KEY_1 .. KEY_20) or .RPB (key = value;) file;
    size of the same-stem raster beside it, if any."""
    path = os.fspath(path)
    lower = path.lower()
    fields: Mapping[str, str | list[str]]
    if lower.endswith("_rpc.txt"):
        fields, stem = _parse_rpc_txt(_read_text(path), path), path[: -len("_rpc.txt")]
    elif lower.endswith(".rpb"):
        fields, stem = _parse_rpb(_read_text(path), path), path[: -len(".rpb")]
    else:
        raise _error(path, "not an RPC file name (expected *_RPC.TXT or *.RPB)")
    image = _sibling_image(stem)
    size = None if image is None else _raster_size(_open_raster(image))
    return RpcRecord(fields, size, (0.0, 0.0), path)


def _key_values(text: str, separator: str) -> dict[str, str]:
    """{key: value} of the lines 'key<separator>value' (first separator; other lines ignored)."""
    pairs = (line.split(separator, 1) for line in text.splitlines() if separator in line)
    return {k.strip(): v.strip() for k, v in pairs}


def _parse_rpc_txt(text: str, path: str) -> dict[str, str | list[str]]:
    values = {k.upper(): v for k, v in _key_values(text, ":").items()}
    fields: dict[str, str | list[str]] = {k: values[k] for k in _SCALARS if k in values}
    for key in COEFF_KEYS:
        names = [f"{key}_{j}" for j in range(1, 21)]
        missing = [n for n in names if n not in values]
        if missing:
            raise _error(
                path, f"missing {', '.join(missing)}; a _RPC.TXT needs {key}_1 .. {key}_20 (is the file truncated?)"
            )
        fields[key] = [values[n] for n in names]
    return fields


def _parse_rpb(text: str, path: str) -> dict[str, str]:
    """The 'name = value;' statements of an .RPB (CPLKeywordParser's syntax, groups ignored);
    lists '( a, b, ... )' become texts of comma-separated numbers (RpcCoefficients reads them)."""
    fields = {}
    for name, value in re.findall(r"(\w+)\s*=\s*([^;=]*);", text):
        if name in _RPB_NAMES:
            fields[_RPB_NAMES[name]] = value.replace("(", " ").replace(")", " ")
    missing = [k for k, v in _RPB_NAMES.items() if v not in fields]
    if missing:
        raise _error(path, f"missing {', '.join(missing)} (not a complete RPC00B .RPB file)")
    return fields


def read_geom(path: Path, image: Path | None = None) -> RpcRecord:
    """RPC of an OSSIM/OTB .geom keyword list ('key: value' lines).

    OSSIM's image coordinates put the first pixel's centre at (0, 0) like RPC00B (its Pleiades
    reader subtracts 1 from DIMAP's LINE_OFF/SAMP_OFF), so line_off/samp_off are taken as they are;
    polynomial_format B is RPC00B's term order, A is reordered. `image` (default: a same-stem
    raster beside the .geom) gives the size and the crop offset (_crop_offset); without one, the
    full image's number_samples x number_lines, when given."""
    path = os.fspath(path)
    kwl = _key_values(_read_text(path), ":")
    fmt = kwl.get("polynomial_format")
    if fmt not in ("A", "B"):
        raise _error(path, f"polynomial_format is {fmt!r}, expected A or B (not an OSSIM RPC keyword list?)")
    fields: dict[str, str | list[str]] = {k: kwl[k.lower()] for k in _SCALARS if k.lower() in kwl}
    for key in COEFF_KEYS:
        names = [f"{key.lower()[:8]}_coeff_{j:02d}" for j in range(20)]
        missing = [n for n in names if n not in kwl]
        if missing:
            raise _error(path, f"missing {', '.join(missing)} (not a complete OSSIM RPC keyword list)")
        terms = [kwl[n] for n in names]
        if fmt == "A":
            reordered = [""] * 20  # every term is set: _A_TO_B is a permutation
            for k, j in enumerate(_A_TO_B):
                reordered[j] = terms[k]
            terms = reordered
        fields[key] = terms
    image = _sibling_image(os.path.splitext(path)[0]) if image is None else os.fspath(image)
    if image is not None:
        ds = _open_raster(image)
        return RpcRecord(fields, _raster_size(ds), _crop_offset(ds, image), path)
    return RpcRecord(fields, _geom_size(kwl, path), (0.0, 0.0), path)


def _geom_size(kwl: Mapping[str, str], path: str) -> tuple[int, int] | None:
    """(number_samples, number_lines) of a .geom, or None when absent."""
    if "number_samples" not in kwl and "number_lines" not in kwl:
        return None
    try:
        size = int(kwl["number_samples"]), int(kwl["number_lines"])
    except (KeyError, ValueError):
        raise _error(
            path,
            "number_samples / number_lines must both be whole numbers: "
            f"{kwl.get('number_samples')!r}, {kwl.get('number_lines')!r}",
        ) from None
    if min(size) <= 0:
        raise _error(path, f"the image size {size} is not positive")
    return size


def _refuse_bias(model: RpcModel, path: Path) -> None:
    if any(getattr(model, "bias", ())):
        raise InputError(
            f"cannot write {path}: the model carries an adjusted bias correction that an RPC file "
            "cannot hold; fit new RPCs to the adjusted model (pushbroom:fitrpc) and write those"
        )


def write_rpc_txt(model: RpcModel, path: Path) -> None:
    """Write `model`'s RPC as a _RPC.TXT (GDAL reads it beside '<stem>.tif' when named
    '<stem>_RPC.TXT'); offsets refer to the model's own raster, crop offset applied. Atomic."""
    _refuse_bias(model, path)
    fields = model.to_fields()
    lines = [f"{k}: {fields[k]}" for k in _SCALARS]
    for key in COEFF_KEYS:
        lines += [f"{key}_{j}: {v}" for j, v in enumerate(fields[key].split(), start=1)]
    write_text(path, "\n".join(lines) + "\n")


def write_rpb(model: RpcModel, path: Path) -> None:
    """Write `model`'s RPC as a .RPB (GDAL's layout; '<stem>.RPB' beside '<stem>.tif'). Atomic."""
    _refuse_bias(model, path)
    fields = model.to_fields()
    names = {v: k for k, v in _RPB_NAMES.items()}
    lines = [
        'satId = "UNKNOWN";',
        'bandId = "P";',
        'SpecId = "RPC00B";',
        "BEGIN_GROUP = IMAGE",
        "\terrBias = 0.0;",
        "\terrRand = 0.0;",
    ]
    lines += [f"\t{names[k]} = {fields[k]};" for k in _SCALARS]
    for key in COEFF_KEYS:
        values = fields[key].split()
        lines.append(f"\t{names[key]} = (")
        lines += [f"\t\t\t{v}," for v in values[:-1]] + [f"\t\t\t{values[-1]});"]
    lines += ["END_GROUP = IMAGE", "END;"]
    write_text(path, "\n".join(lines) + "\n")
