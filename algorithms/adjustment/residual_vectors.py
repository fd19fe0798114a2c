"""Residual vectors of the control and check points of a bundle adjustment, for a map layer.

Per point a line from its reference ground position to that position plus `scale` times its
planimetric residual d = computed - reference (E, N, m), in a projected CRS (default: the UTM zone
of the points), with the point's dE, dN, dH, sigmas, image residual RMS and largest |normalised
residual|:

- control points: d = adjusted - observed (Adjustment.ground_residuals), the adjusted point's
  sigmas, the image residuals v and normalised residuals w of the adjustment;
- check points: d = intersected - reference (bundle.check_points) with their theoretical sigmas;
  their image residuals are those of their own forward intersection with the adjusted models
  (Kornus et al. 2006, section 3.5.1): v = computed - measured at the intersected point, redundancy numbers
  r_i = 1 - p_i a_i (A'PA)^-1 a_i' (a_i the row of A = d(col, row)/d(E, N, U); they sum to 2k - 3
  over a point's k rays) and w = v / (sigma sqrt(r)).

A point is flagged where any of its measurements has |w| > critical (Baarda's data snooping)."""

import os

import numpy as np
from osgeo import ogr

from ..atomic import atomic_path, closing
from ..crs import srs, transform, wgs84
from ..errors import InputError
from ..geodesy import metres_per_degree, offset_enu, utm_epsg
from .bundle import CRITICAL_W

#: default exaggeration of the planimetric residuals on the map: a 1 m residual shows as a 1 km arrow,
#: a few per cent of a SPOT scene's width
DEFAULT_SCALE = 1000.0
VECTOR_DTYPE = np.dtype(
    [
        ("name", "U32"),
        ("role", "U7"),
        ("x0", "f8"),
        ("y0", "f8"),
        ("x1", "f8"),
        ("y1", "f8"),
        ("dE", "f8"),
        ("dN", "f8"),
        ("dH", "f8"),
        ("sigma_e", "f8"),
        ("sigma_n", "f8"),
        ("sigma_h", "f8"),
        ("rms_px", "f8"),
        ("max_w", "f8"),
        ("flagged", "?"),
    ]
)
#: the attributes of a residual vector (VECTOR_DTYPE without the line's end points)
ATTRIBUTES = tuple(n for n in VECTOR_DTYPE.names if n not in ("x0", "y0", "x1", "y1"))


def per_point(point, n_points, v, w):
    """(rms, max_w) per point of measurements `point` (index per measurement) with residuals v and
    normalised residuals w (M, 2): RMS of the 2k coordinates' v and the largest |w| (NaN: none)."""
    count = np.bincount(point, minlength=n_points) * 2
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.bincount(point, (v * v).sum(1), minlength=n_points) / count)
    worst = np.full(n_points, -np.inf)
    np.maximum.at(worst, point, np.nanmax(np.abs(np.where(np.isfinite(w), w, -np.inf)), axis=1))
    return rms, np.where(np.isfinite(worst), worst, np.nan)


def intersection_residuals(models, lon, lat, h, measurements):
    """(v, r) (M, 2): residuals computed - measured of `measurements` (MEAS_DTYPE, `point` indexing
    lon/lat/h) at the points' positions, and their redundancy numbers in each point's forward
    intersection (module docstring)."""
    m = measurements
    n = len(m)
    v, a = np.zeros((n, 2)), np.zeros((n, 2, 3))
    p = m["point"]
    for key in np.unique(m["image_id"]):
        k = np.flatnonzero(m["image_id"] == key)
        d = models[int(key)].partials(lon[p[k]], lat[p[k]], h[p[k]])
        v[k, 0], v[k, 1], a[k] = d["col"] - m["col"][k], d["row"] - m["row"][k], d["d_ground"]
    e_deg, n_deg = metres_per_degree(lat[p], h[p])
    a[:, :, 0] /= e_deg[:, None]
    a[:, :, 1] /= n_deg[:, None]
    weight = 1.0 / m["sigma"] ** 2
    normal = np.zeros((len(lon), 3, 3))
    np.add.at(normal, p, np.einsum("kei,kej->kij", a, a) * weight[:, None, None])
    q = np.linalg.inv(normal[p])
    return v, 1.0 - np.einsum("kei,kij,kej->ke", a, q, a) * weight[:, None]


def residual_vectors(result, check, observations, scale=DEFAULT_SCALE, crs=None, critical=CRITICAL_W):
    """(vectors, crs): VECTOR_DTYPE rows, control points then check points (module docstring), and
    the CRS definition of x0, y0 (reference) and x1, y1 (reference + scale x residual, to first
    order in geodetic coordinates, so the arrow keeps its true azimuth on the map). `result`: the
    Adjustment; `check`: bundle.check_points(result, observations); `observations`: the
    Observations holding the check points; crs: any crs.srs definition (default the UTM zone of the
    points' mean position)."""
    obs = result.observations
    control = np.flatnonzero(obs.points["role"] == "control")
    rms, worst = per_point(obs.measurements["point"], len(obs.points), result.residuals, result.normalised)
    ctrl = np.zeros(control.size, VECTOR_DTYPE)
    ctrl["name"], ctrl["role"] = obs.points["name"][control], "control"
    ctrl["dE"], ctrl["dN"], ctrl["dH"] = result.ground_residuals[control].T
    ctrl["sigma_e"], ctrl["sigma_n"], ctrl["sigma_h"] = result.point_sigmas[control].T
    ctrl["rms_px"], ctrl["max_w"] = rms[control], worst[control]
    ref = [obs.points[k][control] for k in ("lon", "lat", "h")]

    chk_obs = observations.subset(np.isin(observations.points["name"], check["names"]))
    order = {name: k for k, name in enumerate(chk_obs.points["name"])}
    index = np.array([order[name] for name in check["names"]], np.int64)
    pts = chk_obs.points
    d = np.column_stack([check["dE"], check["dN"], check["dH"]])
    lon, lat, h = np.full(len(pts), np.nan), np.full(len(pts), np.nan), np.full(len(pts), np.nan)
    lon[index], lat[index], h[index] = offset_enu(pts["lon"][index], pts["lat"][index], pts["h"][index], d)
    meas = chk_obs.measurements[np.isin(chk_obs.measurements["point"], index)]
    v, r = intersection_residuals(result.parameters.models, lon, lat, h, meas)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = v / (meas["sigma"][:, None] * np.sqrt(np.clip(r, 1e-12, None)))
    rms, worst = per_point(meas["point"], len(pts), v, w)
    chk = np.zeros(index.size, VECTOR_DTYPE)
    chk["name"], chk["role"] = pts["name"][index], "check"
    chk["dE"], chk["dN"], chk["dH"] = d.T
    chk["sigma_e"], chk["sigma_n"], chk["sigma_h"] = check["sigma"].T
    chk["rms_px"], chk["max_w"] = rms[index], worst[index]
    ref = [np.concatenate([c, pts[k][index]]) for c, k in zip(ref, ("lon", "lat", "h"))]

    out = np.concatenate([ctrl, chk])
    out["flagged"] = out["max_w"] > critical
    if crs is None:
        crs = f"EPSG:{utm_epsg(float(np.mean(ref[0])), float(np.mean(ref[1])))}" if len(out) else "EPSG:4326"
    end = offset_enu(*ref, np.column_stack([scale * out["dE"], scale * out["dN"], np.zeros(len(out))]))
    xy = transform(
        wgs84(),
        srs(crs),
        np.column_stack([np.concatenate([ref[0], end[0]]), np.concatenate([ref[1], end[1]])]),
        "the residual vectors",
    )
    n = len(out)
    out["x0"], out["y0"], out["x1"], out["y1"] = xy[:n, 0], xy[:n, 1], xy[n:, 0], xy[n:, 1]
    return out, crs


#: OGR field type per numpy kind of VECTOR_DTYPE's attributes
_OGR_TYPES = {"U": "OFTString", "f": "OFTReal", "b": "OFTInteger"}
_DRIVERS = {".gpkg": "GPKG", ".shp": "ESRI Shapefile", ".geojson": "GeoJSON"}
#: the extensions (without the dot) of the formats write_residual_vectors writes
FORMATS = tuple(ext[1:] for ext in _DRIVERS)


def write_residual_vectors(path, vectors, crs, scale):
    """Write the residual vectors (`residual_vectors`' rows) as a line layer in `crs` with the ATTRIBUTES and
    the map `scale`, to a GeoPackage, shapefile or GeoJSON file by the extension of `path` (atomically)."""
    driver = _DRIVERS.get(os.path.splitext(os.fspath(path))[1].lower())
    if driver is None:
        raise InputError(f"write the residual vectors to a {', '.join(_DRIVERS)} file, not {path}")
    ogr.UseExceptions()
    with (
        atomic_path(path, "the residual vectors") as tmp,
        closing(ogr.GetDriverByName(driver).CreateDataSource(tmp)) as ds,
    ):
        layer = ds.CreateLayer("residual_vectors", srs(crs), ogr.wkbLineString)
        for name in ATTRIBUTES:
            field = ogr.FieldDefn(name, getattr(ogr, _OGR_TYPES[VECTOR_DTYPE[name].kind]))
            if VECTOR_DTYPE[name].kind == "b":
                field.SetSubType(ogr.OFSTBoolean)
            layer.CreateField(field)
        layer.CreateField(ogr.FieldDefn("scale", ogr.OFTReal))
        transaction = ds.TestCapability(ogr.ODsCTransactions)  # GeoPackage, not a shapefile
        if transaction:
            ds.StartTransaction()
        for v in vectors:
            feature = ogr.Feature(layer.GetLayerDefn())
            for name in ATTRIBUTES:
                feature[name] = v[name].item()
            feature["scale"] = float(scale)
            line = ogr.Geometry(ogr.wkbLineString)
            line.AddPoint_2D(float(v["x0"]), float(v["y0"]))
            line.AddPoint_2D(float(v["x1"]), float(v["y1"]))
            feature.SetGeometry(line)
            layer.CreateFeature(feature)
        if transaction:
            ds.CommitTransaction()
        layer = None
    return os.fspath(path)
