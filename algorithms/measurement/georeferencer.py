"""QGIS Georeferencer GCP files (.points), for 2-D reference points measured in one image.

Format of QGIS 3.22 (QgsGeoreferencerMainWindow::saveGCPs / loadGCPs, src/app/georeferencer/
qgsgeorefmainwindow.cpp):

    #CRS: <WKT of the map CRS>              optional; without it QGIS takes the project's CRS
    mapX,mapY,pixelX,pixelY,enable,dX,dY,residual
    <x>,<y>,<pixel x>,<pixel y>,<1 or 0>,<dX>,<dY>,<residual>

one row per point (older files separate the fields by tabs; rows of 4 fields are enabled).
pixelX, pixelY are the point in the source layer's coordinates: a raw image (no geotransform, SPOT
level 1A) is shown with y up, so pixelX = col and pixelY = -row (GDAL's convention, (0, 0) the
top-left corner of the first pixel); a georeferenced source is written as column and line (pixelY
positive), which `read_points` also accepts (all rows of a file use one sign). dX, dY and residual
are the Georeferencer's residuals of its own transformation: written as 0, ignored on reading. The
format has no point names: points read are named prefix + row number."""

import math
import os

import numpy as np

from ..adjustment.control_points import DEFAULT_SIGMAS, ROLES
from ..adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from ..atomic import write_text
from ..crs import reproject, srs, wgs84
from ..errors import InputError
from ..geodesy import utm_epsg
from ..sigmas import IMAGE_SIGMA

HEADER = "mapX,mapY,pixelX,pixelY,enable,dX,dY,residual"
CRS_PREFIX = "#CRS:"


def write_points(path, observations, image_id, crs=None):
    """Write the measurements of image `image_id` in `observations` (control/check points with WGS 84
    lon/lat) as a .points file: map coordinates in `crs` (any crs.srs definition; default the UTM
    zone of the points' mean position), pixelX = col, pixelY = -row. Returns the path."""
    meas = observations.measurements[observations.measurements["image_id"] == int(image_id)]
    if not len(meas):
        raise InputError(f"no point is measured in image {image_id}: nothing to write to {path}")
    points = observations.points[meas["point"]]
    missing = ~(np.isfinite(points["lon"]) & np.isfinite(points["lat"]))
    if missing.any():
        raise InputError(
            f"point {points['name'][missing][0]} has no ground coordinates: a .points file needs "
            "map coordinates for every point"
        )
    if crs is None:
        crs = f"EPSG:{utm_epsg(float(points['lon'].mean()), float(points['lat'].mean()))}"
    target = srs(crs)
    x, y = reproject(points["lon"], points["lat"], wgs84(), target, "the points")
    lines = [f"{CRS_PREFIX} {target.ExportToWkt(['FORMAT=WKT2_2019', 'MULTILINE=NO'])}", HEADER]
    lines += [
        f"{xk!r},{yk!r},{float(m['col'])!r},{-float(m['row'])!r},1,0,0,0"
        for xk, yk, m in zip(x.tolist(), y.tolist(), meas)
    ]
    write_text(path, "\n".join(lines) + "\n")
    return path


def _map_crs(path, text, crs, default=None):
    """The map CRS: the file's #CRS line or `crs` (both given: they must agree), else `default`."""
    given = srs(crs) if crs is not None else None
    if text:
        try:
            stated = srs(text)
        except InputError as exc:
            raise InputError(f"{path} line 1: the #CRS line is no CRS PROJ can read ({exc})") from None
        if given is not None and not stated.IsSame(given):
            raise InputError(
                f"{path} states its CRS as {stated.GetName()!r}, not the {given.GetName()!r} given: "
                "leave the CRS out or correct the file"
            )
        return stated
    if given is None and default is not None:
        given = srs(default)
    if given is None:
        raise InputError(f"{path} has no '#CRS:' line: give the CRS of its map coordinates")
    return given


def _rows(path):
    """(map CRS text or '', [(line number, fields)]) of a .points file."""
    try:
        with open(path, encoding="utf-8-sig") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the GCP file {path}: {exc}") from exc
    numbered = [(k, line.strip()) for k, line in enumerate(lines, start=1) if line.strip()]
    crs_text = ""
    if numbered and numbered[0][1].startswith(CRS_PREFIX):
        crs_text = numbered.pop(0)[1][len(CRS_PREFIX) :].strip()
    if not numbered or not numbered[0][1].lower().startswith("mapx"):
        line = numbered[0][0] if numbered else len(lines) + 1
        raise InputError(f"{path} line {line}: expected the header {HEADER!r} (a QGIS Georeferencer .points file)")
    return crs_text, [
        (k, [c.strip() for c in (text.split(",") if "," in text else text.split("\t"))]) for k, text in numbered[1:]
    ]


def read_points(path, image_id, dem=None, height=None, crs=None, role="control", prefix="GEO", default_crs=None):
    """Observations of the enabled rows of a .points file measured in image `image_id`: points
    prefix + row number (1 = the first point row) of `role`, lon/lat from the map coordinates
    (CRS: the file's #CRS line, else `crs`, else `default_crs`: QGIS's map CRS), ellipsoidal h from
    `dem` (algorithms.dem.Dem) at the point, else (or where the DEM has no height) `height`; default
    sigmas (control_points.DEFAULT_SIGMAS, IMAGE_SIGMA px). InputError naming the line for a malformed row."""
    path = os.fspath(path)
    if role not in ROLES:
        raise InputError(f"the role must be one of {', '.join(ROLES)}, not {role!r}")
    if dem is None and height is None:
        raise InputError("a .points file has no heights: give a DEM or a height for its points")
    crs_text, rows = _rows(path)
    values, lines = [], []
    for number, (line, cells) in enumerate(rows, start=1):
        if len(cells) < 4:
            raise InputError(f"{path} line {line}: {len(cells)} field(s), expected at least mapX,mapY,pixelX,pixelY")
        try:
            x, y, px, py = (float(c) for c in cells[:4])
            enabled = int(float(cells[4])) != 0 if len(cells) > 4 and cells[4] else True
        except ValueError:
            raise InputError(f"{path} line {line}: {','.join(cells)!r} is not numbers") from None
        if not all(math.isfinite(v) for v in (x, y, px, py)):
            raise InputError(f"{path} line {line}: coordinates must be finite numbers")
        if enabled:
            values.append((number, x, y, px, py))
            lines.append(line)
    if not values:
        raise InputError(f"{path} has no enabled point")
    number, x, y, px, py = (np.array(v) for v in zip(*values))
    if (py > 0).any() and (py < 0).any():
        k = int(np.flatnonzero(py > 0)[0])
        raise InputError(
            f"{path} line {lines[k]}: pixelY {py[k]} is positive where other rows are negative "
            "(-row, a raw image): rows must all use one convention"
        )
    lon, lat = reproject(x, y, _map_crs(path, crs_text, crs, default_crs), wgs84(), f"the points of {path}")
    h = dem.height(lon, lat) if dem is not None else np.full(len(lon), np.nan)
    h = np.where(np.isfinite(h), h, np.nan if height is None else float(height))
    if not np.isfinite(h).all():
        k = int(np.flatnonzero(~np.isfinite(h))[0])
        raise InputError(
            f"{path} line {lines[k]}: the DEM has no height at ({lon[k]:.6f}, {lat[k]:.6f}); give a "
            "DEM covering the points or a height"
        )
    points = np.zeros(len(lon), POINT_DTYPE)
    points["name"] = [f"{prefix}{n}" for n in number]
    points["role"] = role
    points["lon"], points["lat"], points["h"] = lon, lat, h
    points["sigma_e"], points["sigma_n"], points["sigma_h"] = DEFAULT_SIGMAS
    meas = np.zeros(len(lon), MEAS_DTYPE)
    meas["point"] = np.arange(len(lon))
    meas["image_id"], meas["col"], meas["row"], meas["sigma"] = int(image_id), px, np.abs(py), IMAGE_SIGMA
    return Observations(points, meas).check()
