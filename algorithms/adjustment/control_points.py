"""Control and check points of a block: CSV import and export.

CSV format: one header row, then one row per point; column names are matched case-insensitively,
the delimiter is a comma, semicolon or tab, the encoding UTF-8 or, told by a byte order mark, UTF-16 or UTF-32
(what spreadsheets write as "Unicode text"; `decode`).

- `id` (or `name`): the point name, unique, at most 32 characters;
- `role`: control or check (optional column; an empty cell or no column: the default role;
  ids named in `check_ids` are check points whatever the column says);
- `lon`, `lat`: WGS 84 longitude/latitude in degrees, or `x`, `y`: easting/northing (or
  longitude/latitude) in the CRS given (EPSG code or WKT; x is always the easting or longitude),
  converted to WGS 84 through PROJ;
- `h` (or `height`, `z`): height in metres, ellipsoidal (WGS 84), or orthometric (EGM96) with
  heights="orthometric": h = H + N, the geoid undulation N from PROJ's EGM96 grid
  (us_nga_egm96_15.tif or egm96_15.gtx) through the transformation EPSG:4326+5773 -> EPSG:4979;
- `sigma_e`, `sigma_n`, `sigma_h`: a priori standard deviations (m; optional, empty: defaults,
  Kornus et al. 2006: 2.5, 2.5, 2.2 m);
- `<image>_col<suffix>`, `<image>_row<suffix>` and optionally `<image>_sigma<suffix>` (px) per
  block image: the measurement in that image (GDAL pixel convention, centre of the first pixel
  (0.5, 0.5)); empty cells: not measured there. `suffix` is "" by default; the simulator's
  points.csv has its measurements in `<image>_col_meas`, `<image>_row_meas` (suffix "_meas").

Other columns are ignored with a warning. Errors name the line and column.

Storage in the block: block/control_points.py (through block.Block).
"""

from __future__ import annotations

import codecs
import csv
import dataclasses
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import progress
from ..atomic import write_text
from ..crs import egm96_undulation, reproject, srs as parse_crs, wgs84
from ..errors import InputError
from ..progress import Feedback
from ..sigmas import IMAGE_SIGMA
from . import point_plausibility
from .observations import MEAS_DTYPE, POINT_DTYPE, Observations

DEFAULT_SIGMAS = (2.5, 2.5, 2.2)  # ground east, north, height (m), Kornus et al. 2006
HEIGHT_TYPES = ("ellipsoidal", "orthometric")
ROLES = ("control", "check")
ALIASES = {"name": "id", "height": "h", "z": "h"}
BASE_COLUMNS = ("id", "role", "lon", "lat", "x", "y", "h", "sigma_e", "sigma_n", "sigma_h")
NAME_LENGTH = int(POINT_DTYPE["name"].itemsize // 4)


def orthometric_to_ellipsoidal(lon, lat, height):
    """Ellipsoidal heights h = H + N of EGM96 orthometric heights H at WGS 84 lon/lat (degrees)."""
    lon, lat, height = (np.atleast_1d(np.asarray(v, float)) for v in (lon, lat, height))
    return height + egm96_undulation(lon, lat)


def to_wgs84(x, y, definition):
    """WGS 84 lon, lat (degrees) of x, y (easting/longitude first) in CRS `definition` (EPSG code or WKT)."""
    source = parse_crs(definition)
    if source.IsCompound() or source.IsVertical():
        raise InputError("give the horizontal CRS of x/y only and choose the height type with the heights option")
    return reproject(x, y, source, wgs84(), "the x/y coordinates")


#: byte order marks and the encodings they announce (UTF-32 before UTF-16, whose mark begins UTF-32 LE's)
BOMS = (
    (codecs.BOM_UTF8, "utf-8-sig"),
    (codecs.BOM_UTF32_LE, "utf-32"),
    (codecs.BOM_UTF32_BE, "utf-32"),
    (codecs.BOM_UTF16_LE, "utf-16"),
    (codecs.BOM_UTF16_BE, "utf-16"),
)


def decode(data, path):
    """The text of a point file's bytes `data`: in the encoding its byte order mark announces (BOMS), else UTF-16
    where every other byte of ASCII text is zero (UTF-16 without a mark), else UTF-8; InputError naming the
    encoding problem and the line otherwise."""
    encoding = next((name for bom, name in BOMS if data.startswith(bom)), None)
    if encoding is None and len(data) >= 2 and data[1::2].count(0) > 0.9 * (len(data) // 2):
        encoding = "utf-16-le"
    elif encoding is None and len(data) >= 2 and data[0::2].count(0) > 0.9 * (len(data) // 2):
        encoding = "utf-16-be"
    try:
        return data.decode(encoding or "utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        given = f"{encoding.upper()} (as its start tells)" if encoding else "UTF-8"
        raise InputError(
            f"the point file {path} is not {given} text: byte {exc.start} (line {line}, "
            f"{data[exc.start : exc.start + 1]!r}) is not valid there. Save it as UTF-8 (in a spreadsheet: "
            "CSV UTF-8), or as Unicode text (UTF-16)"
        ) from None


class _Table:
    """The cells of a CSV file with its line numbers and the column roles of its header."""

    def __init__(self, path, image_names, suffix):
        self.path = os.fspath(path)
        try:
            with open(self.path, "rb") as f:
                data = f.read()
        except FileNotFoundError:
            raise InputError(f"the point file {self.path} does not exist: check the path") from None
        except OSError as exc:
            raise InputError(f"cannot read the point file {self.path}: {exc.strerror}") from exc
        text = decode(data, self.path)
        first = text.splitlines()[0] if text.strip() else ""
        delimiter = max(",;\t", key=first.count)
        reader = csv.reader(io.StringIO(text), delimiter=delimiter)
        try:
            header = next(reader, None)
        except csv.Error as exc:  # e.g. a lone carriage return inside the header line
            raise InputError(f"{self.path} line 1: {exc}") from exc
        if not header or not any(h.strip() for h in header):
            raise InputError(f"{self.path} is empty: the first line must name the columns")
        self.header = [h.strip() for h in header]
        self.rows = []
        try:
            for cells in reader:
                if any(c.strip() for c in cells):
                    if len(cells) > len(self.header):
                        raise InputError(
                            f"{self.path} line {reader.line_num}: {len(cells)} fields, the header "
                            f"has {len(self.header)}"
                        )
                    cells = [c.strip() for c in cells]
                    self.rows.append((reader.line_num, cells + [""] * (len(self.header) - len(cells))))
        except csv.Error as exc:
            raise InputError(f"{self.path} line {reader.line_num}: {exc}") from exc
        self._columns(image_names, suffix)

    def _columns(self, image_names, suffix):
        """self.base {key: index}, self.images {name: {col, row[, sigma]: index}}, self.ignored."""
        self.base, self.images, self.ignored, unknown = {}, {}, [], []
        by_lower = {}
        for name in image_names:
            by_lower.setdefault(name.lower(), []).append(name)
        for index, title in enumerate(self.header):
            low = title.lower()
            key = ALIASES.get(low, low)
            if key in BASE_COLUMNS:
                if key in self.base:
                    raise InputError(
                        f"{self.path}: columns {self.header[self.base[key]]!r} and {title!r} both give {key}"
                    )
                self.base[key] = index
                continue
            ending = next(
                (
                    k
                    for k in ("col", "row", "sigma")
                    if low.endswith(f"_{k}{suffix}".lower()) and len(low) > len(f"_{k}{suffix}")
                ),
                None,
            )
            if ending is None:
                self.ignored.append(title)
                continue
            prefix = title[: len(title) - len(f"_{ending}{suffix}")]
            matches = [prefix] if prefix in image_names else by_lower.get(prefix.lower(), [])
            image = matches[0] if len(matches) == 1 else None
            if image is None:
                unknown.append(title)
                continue
            columns = self.images.setdefault(image, {})
            if ending in columns:
                raise InputError(f"{self.path}: two {ending} columns for image {image}")
            columns[ending] = index
        if unknown:
            raise InputError(
                f"{self.path}: column(s) {', '.join(unknown)} name images that are not in the block; "
                f"the block's images are {', '.join(image_names)}"
            )
        for image, columns in self.images.items():
            for need in ("col", "row"):
                if need not in columns:
                    raise InputError(f"{self.path}: image {image} has no column {image}_{need}{suffix}")
        if "id" not in self.base:
            raise InputError(f"{self.path}: no column 'id' (the point names)")
        has_geo, has_xy = {"lon", "lat"} & set(self.base), {"x", "y"} & set(self.base)
        if has_geo and has_xy:
            raise InputError(f"{self.path}: give either lon/lat or x/y columns, not both")
        pair = ("lon", "lat") if has_geo or not has_xy else ("x", "y")
        for need in pair + ("h",):
            if need not in self.base:
                raise InputError(
                    f"{self.path}: no column '{need}'" + (" (or x/y with a CRS)" if need in ("lon", "lat") else "")
                )
        self.horizontal = pair

    def cell(self, cells, key):
        """The text of column `key` of a row ('' without the column)."""
        return cells[self.base[key]] if key in self.base else ""

    def number(self, line, cells, index, positive=False):
        """The finite (or positive) number in column `index` of a row; InputError naming line and column."""
        text = cells[index]
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (positive and value <= 0):
            raise InputError(
                f"{self.path} line {line}, column {self.header[index]}: {text!r} is not a "
                f"{'positive' if positive else 'finite'} number"
            )
        return value


@dataclass(frozen=True)
class CsvOptions:
    """How to read a point file (module docstring): `crs` the CRS of x/y columns (EPSG code or WKT; default
    WGS 84); `heights` one of HEIGHT_TYPES; `default_role` the role of a point without one; `check_ids` names
    points that are check points whatever their role column says; `sigmas` the default ground sigmas (m, E,
    N, H) and `image_sigma` the default measurement sigma (px); `suffix` that of the measurement columns."""

    crs: str | int | None = None
    heights: str = "ellipsoidal"
    default_role: str = "control"
    check_ids: Sequence[str] = ()
    sigmas: Sequence[float] = DEFAULT_SIGMAS
    image_sigma: float = IMAGE_SIGMA
    suffix: str = ""


def read_csv(
    path: str | os.PathLike[str],
    image_names: dict[str, int],
    options: CsvOptions | None = None,
    feedback: Feedback | None = None,
) -> Observations:
    """Observations (control/check points and their image measurements) from the CSV `path`
    (format in the module docstring), read with CsvOptions `options` (default: its defaults). `image_names`
    maps the block's image names to their ids ({name: id}). Measurements are ordered by point, then
    image id."""
    return _read_csv(path, image_names, options or CsvOptions(), feedback)[0]


def _read_csv(
    path: str | os.PathLike[str], image_names: dict[str, int], options: CsvOptions, feedback: Feedback | None
) -> tuple[Observations, np.ndarray]:
    """read_csv's Observations and, per point, whether its x/y looked like degrees in a projected CRS."""
    crs, heights, default_role, check_ids = options.crs, options.heights, options.default_role, options.check_ids
    sigmas, image_sigma, suffix = options.sigmas, options.image_sigma, options.suffix
    if heights not in HEIGHT_TYPES:
        raise InputError(f"heights must be one of {', '.join(HEIGHT_TYPES)}, not {heights!r}")
    if default_role not in ROLES:
        raise InputError(f"the default role must be one of {', '.join(ROLES)}, not {default_role!r}")
    if not all(s > 0 for s in list(sigmas) + [image_sigma]):
        raise InputError(f"default sigmas must be positive, got {list(sigmas)} m and {image_sigma} px")
    log = progress.ensure(feedback)
    table = _Table(path, image_names, suffix)
    if table.ignored:
        log.pushInfo(f"warning: ignored column(s) of {table.path}: {', '.join(table.ignored)}")
    if table.horizontal == ("lon", "lat") and crs is not None and not parse_crs(crs).IsSame(wgs84()):
        log.pushInfo("warning: lon/lat columns are WGS 84 degrees; the CRS applies to x/y columns only")
    points = np.zeros(len(table.rows), POINT_DTYPE)
    meas: list[tuple[int, int, float, float, float]] = []
    seen: dict[str, int] = {}
    image_ids = [(image_names[name], table.images[name]) for name in image_names if name in table.images]
    for k, (line, cells) in enumerate(table.rows):
        name = table.cell(cells, "id")
        # a control character (a NUL, a tab) is no part of a name, and numpy's text drops a NUL at the end
        if not name or len(name) > NAME_LENGTH or not name.isprintable():
            raise InputError(
                f"{table.path} line {line}: the point id must have 1 to {NAME_LENGTH} printable characters, "
                f"got {name!r}"
            )
        if name in seen:
            raise InputError(f"{table.path} line {line}: point id {name!r} is used again (first on line {seen[name]})")
        seen[name] = line
        role = table.cell(cells, "role").lower() or default_role
        if role not in ROLES:
            raise InputError(
                f"{table.path} line {line}, column {table.header[table.base['role']]}: role "
                f"{role!r} is not one of {', '.join(ROLES)}"
            )
        points[k]["name"], points[k]["role"] = name, role
        horizontal = [table.number(line, cells, table.base[key]) for key in table.horizontal]
        points[k]["lon"], points[k]["lat"] = horizontal
        points[k]["h"] = table.number(line, cells, table.base["h"])
        for key, default in zip(("sigma_e", "sigma_n", "sigma_h"), sigmas):
            points[k][key] = (
                table.number(line, cells, table.base[key], positive=True) if table.cell(cells, key) else default
            )
        for image_id, columns in image_ids:
            given = [bool(cells[columns[key]]) for key in ("col", "row")]
            if not any(given):
                continue
            if not all(given):
                missing = columns["row" if given[0] else "col"]
                raise InputError(
                    f"{table.path} line {line}, column {table.header[missing]}: empty, but the "
                    "other image coordinate is given (give both or neither)"
                )
            sigma = (
                table.number(line, cells, columns["sigma"], positive=True)
                if "sigma" in columns and cells[columns["sigma"]]
                else image_sigma
            )
            meas.append(
                (
                    k,
                    image_id,
                    table.number(line, cells, columns["col"]),
                    table.number(line, cells, columns["row"]),
                    sigma,
                )
            )
    if not len(points):
        raise InputError(f"{table.path} has no points (only a header)")
    check_ids = [c.strip() for c in (check_ids or []) if c.strip()]
    unknown = sorted(set(check_ids) - set(seen))
    if unknown:
        raise InputError(f"check point id(s) {', '.join(unknown)} are not in {table.path}")
    points["role"][np.isin(points["name"], check_ids)] = "check"
    degrees = _ground_to_wgs84(points, table, crs, heights, seen)
    return Observations(points, np.array(meas, MEAS_DTYPE)).sorted().check(), degrees


def _ground_to_wgs84(points, table, crs, heights, lines):
    """Convert the points' x/y (table.horizontal) and heights in place to WGS 84 lon/lat and
    ellipsoidal h; coordinates out of range name their line. Returns per point whether its x/y were
    within +-180, +-90 in a projected CRS (degrees given as projected coordinates?)."""
    degrees = np.zeros(len(points), bool)
    if table.horizontal == ("x", "y"):
        if crs is not None and parse_crs(crs).IsProjected():
            degrees = (np.abs(points["lon"]) <= 180.0) & (np.abs(points["lat"]) <= 90.0)
        points["lon"], points["lat"] = to_wgs84(points["lon"], points["lat"], 4326 if crs is None else crs)
    bad = ~(
        np.isfinite(points["lon"])
        & np.isfinite(points["lat"])
        & (np.abs(points["lat"]) <= 90.0)
        & (np.abs(points["lon"]) <= 360.0)
    )
    if bad.any():
        p = points[bad][0]
        raise InputError(
            f"{table.path} line {lines[p['name']]}: point {p['name']} gives lon {p['lon']}, lat "
            f"{p['lat']}, not WGS 84 degrees: are lon/lat swapped, or are these projected "
            "coordinates (name the columns x, y and give their CRS)?"
        )
    if heights == "orthometric":
        points["h"] = orthometric_to_ellipsoidal(points["lon"], points["lat"], points["h"])
    return degrees


def write_csv(path, observations, image_names):
    """Write `observations` as a CSV that `read_csv` reads back exactly (numbers as Python's
    shortest round-trip repr; columns id, role, lon, lat, h, sigma_e, sigma_n, sigma_h, then
    <image>_col, <image>_row, <image>_sigma per image of `image_names` ({name: id}))."""
    points, meas = observations.points, observations.measurements
    names_of = {image_id: name for name, image_id in image_names.items()}
    unknown = sorted(set(meas["image_id"].tolist()) - set(names_of))
    if unknown:
        raise InputError(f"measurements in image id(s) {unknown}, which are not among {sorted(names_of)}")
    columns = {image_id: k for k, image_id in enumerate(image_names.values())}
    cells = np.full((len(points), 3 * len(columns)), "", dtype=object)
    for m in meas:
        c = 3 * columns[int(m["image_id"])]
        cells[m["point"], c : c + 3] = [repr(float(m[key])) for key in ("col", "row", "sigma")]
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(
        ["id", "role", "lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h"]
        + [f"{name}_{key}" for name in image_names for key in ("col", "row", "sigma")]
    )
    for p, extra in zip(points, cells):
        writer.writerow(
            [p["name"], p["role"]]
            + [
                "" if math.isnan(p[key]) else repr(float(p[key]))
                for key in ("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h")
            ]
            + list(extra)
        )
    write_text(path, text.getvalue())
    return path


def summary(observations, image_names):
    """Counts per role and per image, one line ("control 5, check 2; HRG: 5 control, 2 check; ...")."""
    points, meas = observations.points, observations.measurements
    text = ", ".join(f"{role} {int((points['role'] == role).sum())}" for role in ROLES)
    roles = points["role"][meas["point"]]
    for name, image_id in image_names.items():
        here = meas["image_id"] == image_id
        text += f"; {name}: " + ", ".join(f"{int((here & (roles == role)).sum())} {role}" for role in ROLES)
    return text


def check_extent(observations, images):
    """InputError if a measurement lies outside its image (`images`: Block.images() rows)."""
    sizes = {r["id"]: (r["cols"], r["rows"]) for r in images}
    names = {r["id"]: r["name"] for r in images}
    for m in observations.measurements:
        cols, rows = sizes[int(m["image_id"])]
        if not (0.0 <= m["col"] <= cols and 0.0 <= m["row"] <= rows):
            raise InputError(
                f"point {observations.points['name'][m['point']]}: measurement ({m['col']}, {m['row']}) "
                f"lies outside image {names[int(m['image_id'])]} ({cols} x {rows} px): are col and "
                "row swapped or the image columns mixed up?"
            )


def check_plausible(blk, observations, degrees_as_projected=None, keep=False, feedback=None):
    """Refuse (InputError naming them) the points that do not lie where the images of the block `blk`
    (block.Block) are (point_plausibility.py), or with `keep` only warn about them through `feedback`."""
    images = blk.images()
    models = blk.models()
    heights = list(blk.height_range() or ()) + observations.points["h"].tolist()
    footprints = point_plausibility.Footprints(models, {r["id"]: r["name"] for r in images}, heights)
    lines = point_plausibility.implausible_points(observations, footprints, degrees_as_projected)
    if not lines:
        return []
    shown = "; ".join(lines[:10]) + (f"; and {len(lines) - 10} more" if len(lines) > 10 else "")
    if not keep:
        raise InputError(
            f"{len(lines)} point(s) do not lie where the block's images are, nothing was imported: "
            f"{shown}. Correct them, or import them anyway with the option to keep such points"
        )
    progress.ensure(feedback).pushInfo(
        f"warning: kept {len(lines)} point(s) that do not lie where the block's images are: {shown}"
    )
    return lines


def import_csv(
    blk: Any,  # block.Block (the block package imports this module)
    csv_path: str,
    mode: str = "replace",
    feedback: Feedback | None = None,
    keep_implausible: bool = False,
    replace_fewer: bool = False,
    **options: Any,
) -> Observations:
    """Read `csv_path` (`read_csv` with the CsvOptions `options`) against the images of the block `blk` (block.Block),
    check the measurements lie inside their images and the points where the images are (`check_plausible`;
    refused unless `keep_implausible`) and store the points (Block.save_control_points, `mode` replace or
    merge; far fewer points or measurements than the block holds only with `replace_fewer`). Returns the
    points now in the block."""
    images = blk.images()
    names = {r["name"]: r["id"] for r in images}
    unknown = set(options) - {f.name for f in dataclasses.fields(CsvOptions)}
    if unknown:
        raise TypeError(f"unknown option(s) {sorted(unknown)}")
    observations, degrees = _read_csv(csv_path, names, CsvOptions(**options), feedback)
    check_extent(observations, images)
    check_plausible(blk, observations, degrees, keep_implausible, feedback)
    return blk.save_control_points(observations, mode=mode, feedback=feedback, names=names, replace_fewer=replace_fewer)


def export_csv(blk, csv_path):
    """Write the control/check points of the block `blk` (block.Block) to `csv_path` (`write_csv`);
    returns them."""
    observations = blk.control_points()
    if not len(observations.points):
        raise InputError(f"block {blk.path} has no control or check points: import some first (pushbroom:importpoints)")
    write_csv(csv_path, observations, blk.image_ids())
    return observations
