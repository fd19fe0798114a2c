"""Point clouds of intersected object points: LAS/LAZ (laspy) or a GeoPackage point layer (OGR).

x, y are in a projected CRS (default: the WGS 84 UTM zone of the points' centre, geodesy.utm_epsg),
z is the WGS 84 ellipsoidal height in metres; per-point values (group, rho, sigma_h, rays, ...) go
into LAS extra bytes dimensions or GeoPackage fields, and the colour fields red, green and blue (uint16, where
given) into the LAS colour fields of point format 7. LAS files are LAS 1.4, point format 6 (7 with colours), with
the CRS as an OGC WKT VLR (global encoding WKT bit set) and 1 mm coordinate resolution (1e-8 degree
for a geographic CRS). A GeoPackage holds 3-D points (wkbPoint25D); it is chosen by the extension
.gpkg for up to GPKG_MAX_POINTS points (larger clouds belong in LAS/LAZ: QGIS draws them as point
clouds), or always with fmt="gpkg". The WKT is OGC WKT 1 of the horizontal CRS, as LAS 1.4 asks; that
z is the ellipsoidal height is said in the LAS header's generating software and in this docstring.
Every write is atomic."""

import os
import warnings

import numpy as np
from osgeo import ogr

from .. import progress
from ..atomic import atomic_path, closing
from ..crs import check_output_crs, reproject, srs as parse_crs, wgs84
from ..errors import InputError
from ..geodesy import utm_epsg

GPKG_MAX_POINTS = 100_000
#: the per-point fields that go into the LAS colour fields (point format 7) where all three are given
COLOUR_FIELDS = ("red", "green", "blue")
FORMATS = ("las", "laz", "gpkg")


#: the point layer of a GeoPackage point cloud
GPKG_LAYER = "points"


def output_format(path, count, fmt=None):
    """'las', 'laz' or 'gpkg' for writing `count` points to `path` (module docstring)."""
    if fmt is not None:
        if fmt not in FORMATS:
            raise InputError(f"point cloud format must be one of {', '.join(FORMATS)}, not {fmt!r}")
        return fmt
    ext = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
    if ext not in FORMATS:
        raise InputError(f"a point cloud is written as .las, .laz or .gpkg, not {os.fspath(path)}")
    if ext == "gpkg" and count > GPKG_MAX_POINTS:
        raise InputError(
            f"{count} points are too many for a GeoPackage (at most {GPKG_MAX_POINTS}): write a "
            ".laz or .las file, which QGIS shows as a point cloud"
        )
    return ext


def output_srs(crs=None, lon=None, lat=None, what="the points"):
    """osr.SpatialReference (x = east / longitude first) of `crs` (EPSG code, 'EPSG:n', WKT, PROJ
    string or osr.SpatialReference), or of the UTM zone of the centre of (lon, lat). A `crs` used far from
    the centre of (lon, lat), where given, is an InputError naming `what` (crs.check_output_crs)."""
    finite = None if lon is None else np.isfinite(lon) & np.isfinite(lat)
    if crs is None or crs == "":
        if finite is None or not finite.any():
            raise InputError("no point to choose the UTM zone from: give the output CRS")
        return parse_crs(utm_epsg(float(np.mean(lon[finite])), float(np.mean(lat[finite]))))
    target = parse_crs(crs)
    if finite is not None and finite.any():
        check_output_crs(target, float(np.mean(lon[finite])), float(np.mean(lat[finite])), what)
    return target


def cloud_fields(result, group=None, rho=None):
    """Per converged point of an Intersection: point_id, group and rho (when given, one per point of
    `result`), rays, sigma_h (a priori, m) and sigma0, as compact dtypes for LAS extra bytes."""
    ok = result.ok
    fields = {"point_id": result.point[ok].astype(np.int64)}
    if group is not None:
        fields["group"] = np.asarray(group)[ok].astype(np.uint8)
    if rho is not None:
        fields["rho"] = np.asarray(rho)[ok].astype(np.float32)
    fields["rays"] = result.rays[ok].astype(np.uint8)
    fields["sigma_h"] = result.sigma[ok, 2].astype(np.float32)
    fields["sigma0"] = result.sigma0[ok].astype(np.float32)
    return fields


def write_point_cloud(path, lon, lat, h, fields=None, crs=None, fmt=None, feedback=None):
    """Write points (lon, lat in degrees, h ellipsoidal m) with per-point `fields` (dict name ->
    array) to `path` in `crs` (default: UTM of the points); format by `fmt` or the extension
    (output_format). Returns (path, srs, format)."""
    lon, lat, h = (np.asarray(v, float).ravel() for v in (lon, lat, h))
    fields = {name: np.asarray(values).ravel() for name, values in (fields or {}).items()}
    if any(v.size != lon.size for v in [lat, h, *fields.values()]):
        raise InputError("lon, lat, h and every field need one value per point")
    if not (np.isfinite(lon).all() and np.isfinite(lat).all() and np.isfinite(h).all()):
        raise InputError("point coordinates must be finite: leave out the points that were not intersected")
    fmt = output_format(path, lon.size, fmt)
    srs = output_srs(crs, lon, lat)
    progress.step(feedback, 0)
    x, y = reproject(lon, lat, wgs84(), srs)
    progress.step(feedback, 20)
    if fmt == "gpkg":
        write_gpkg(path, x, y, h, fields, srs, feedback=feedback)
    else:
        write_las(path, x, y, h, fields, srs, compress=fmt == "laz")
    progress.step(feedback, 100)
    return os.fspath(path), srs, fmt


def save_part(path, lon, lat, h, fields):
    """Write a part of a cloud (lon, lat in degrees, h ellipsoidal m, `fields`) to the .npz `path` atomically:
    what a tile task hands on to `write_point_cloud_parts` (load_part reads it)."""
    with atomic_path(path, "a part of the point cloud") as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, lon=lon, lat=lat, h=h, **fields)
    return path


def load_part(path):
    """(lon, lat, h, fields) of a part written by save_part."""
    with np.load(path, allow_pickle=False) as data:
        return data["lon"], data["lat"], data["h"], {k: data[k] for k in data.files if k not in ("lon", "lat", "h")}


def write_point_cloud_parts(path, parts, count, centre=None, crs=None, fmt=None, feedback=None):
    """`write_point_cloud` of a cloud in parts: `parts` is a list of functions, each returning the
    (lon, lat, h, fields) of a part, called one at a time; `count` the points of all parts; `centre`
    (lon, lat) of the cloud chooses the UTM zone where `crs` is None. LAS/LAZ are written part by part
    (write_las_parts: memory follows the part); a GeoPackage, at most GPKG_MAX_POINTS, at once.
    Returns (path, srs, format)."""
    fmt = output_format(path, count, fmt)
    lon, lat = centre if centre is not None else (np.nan, np.nan)
    srs = output_srs(crs, np.array([lon], float), np.array([lat], float))
    if fmt == "gpkg":
        loaded = [load() for load in parts]
        fields = {name: np.concatenate([p[3][name] for p in loaded]) for name in (loaded[0][3] if loaded else {})}
        return write_point_cloud(
            path,
            *(np.concatenate([p[i] for p in loaded]) for i in range(3)),
            fields,
            crs=srs,
            fmt=fmt,
            feedback=feedback,
        )

    def projected():
        for k, load in enumerate(parts):
            lon, lat, h, fields = load()
            x, y = reproject(np.asarray(lon, float), np.asarray(lat, float), wgs84(), srs)
            yield x, y, np.asarray(h, float), fields
            progress.step(feedback, 100.0 * (k + 1) / len(parts))

    write_las_parts(path, projected(), srs, compress=fmt == "laz")
    return os.fspath(path), srs, fmt


def laspy_module():
    """laspy, imported quietly."""
    with warnings.catch_warnings():
        # laspy imports pyproj where installed, which warns about its data; the CRS goes through OSR here
        warnings.simplefilter("ignore", UserWarning)
        import laspy
    return laspy


def write_las(path, x, y, z, fields, srs, compress=False):
    """LAS 1.4 / point format 6 (LAZ when `compress`) with the WKT of `srs` and `fields` as extra bytes."""
    return write_las_parts(path, [(x, y, z, fields)], srs, compress)


def write_las_parts(path, parts, srs, compress=False):
    """`write_las` from `parts`, an iterable of (x, y, z, fields) in `srs` taken one at a time, so that
    memory follows the part, not the cloud (every part has the same fields). The header's offsets are
    the floor of the first part's minima: coordinates are stored as 32-bit integers of the scale (1 mm),
    so the cloud may reach 2 147 km beyond them."""
    laspy = laspy_module()
    if compress and not laspy.LazBackend.detect_available():
        raise InputError(
            "writing LAZ needs the lazrs or laszip Python package (pip install lazrs); write a .las file instead"
        )
    with atomic_path(path) as tmp:
        writer = None
        try:
            for x, y, z, fields in parts:
                if writer is None:
                    coloured = set(COLOUR_FIELDS) <= set(fields)
                    header = laspy.LasHeader(point_format=7 if coloured else 6, version="1.4")
                    header.global_encoding.wkt = True
                    header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(srs.ExportToWkt()))
                    header.generating_software = "Pushbroom (z: ellipsoidal h)"
                    step = 1e-8 if srs.IsGeographic() else 1e-3
                    header.scales = np.array([step, step, 1e-3])
                    header.offsets = np.array([np.floor(v.min()) if v.size else 0.0 for v in (x, y, z)])
                    header.add_extra_dims(
                        [
                            laspy.ExtraBytesParams(name=name, type=values.dtype)
                            for name, values in fields.items()
                            if not (coloured and name in COLOUR_FIELDS)
                        ]
                    )
                    writer = laspy.open(tmp, mode="w", header=header, do_compress=compress)
                records = laspy.ScaleAwarePointRecord.zeros(len(x), header=writer.header)
                records.x, records.y, records.z = x, y, z
                for name, values in fields.items():
                    records[name] = values
                writer.write_points(records)
        finally:
            if writer is not None:
                writer.close()
    return path


OGR_TYPES = {"i": ogr.OFTInteger64, "u": ogr.OFTInteger64, "f": ogr.OFTReal, "b": ogr.OFTInteger}


def write_gpkg(path, x, y, z, fields, srs, feedback=None):
    """A GeoPackage with one 3-D point layer GPKG_LAYER in `srs` and `fields` as attributes."""
    ogr.UseExceptions()
    with atomic_path(path) as tmp, closing(ogr.GetDriverByName("GPKG").CreateDataSource(tmp)) as ds:
        layer = ds.CreateLayer(GPKG_LAYER, srs, ogr.wkbPoint25D, options=["FID=fid", "GEOMETRY_NAME=geom"])
        for name, values in fields.items():
            layer.CreateField(ogr.FieldDefn(name, OGR_TYPES.get(values.dtype.kind, ogr.OFTString)))
        columns = [(name, values.tolist()) for name, values in fields.items()]
        ds.StartTransaction()
        defn = layer.GetLayerDefn()
        for i, (xi, yi, zi) in enumerate(zip(x.tolist(), y.tolist(), z.tolist())):
            if i % 10000 == 0:
                progress.step(feedback, 20 + 75 * i / len(x))
            feat = ogr.Feature(defn)
            for name, values in columns:
                feat[name] = values[i]
            point = ogr.Geometry(ogr.wkbPoint25D)
            point.AddPoint(xi, yi, zi)
            feat.SetGeometryDirectly(point)
            layer.CreateFeature(feat)
        ds.CommitTransaction()
        layer = None
    return path
