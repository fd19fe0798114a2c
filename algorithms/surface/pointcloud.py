"""Point clouds of intersected object points: LAS/LAZ (laspy) or a GeoPackage point layer (OGR).

x, y are in a projected CRS (default: the WGS 84 UTM zone of the points' centre, geodesy.utm_epsg),
z is the WGS 84 ellipsoidal height in metres; per-point values (group, rho, sigma_h, rays, ...) go
into LAS extra bytes dimensions or GeoPackage fields. LAS files are LAS 1.4, point format 6, with
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
from ..crs import reproject, srs as parse_crs, wgs84
from ..errors import InputError
from ..geodesy import utm_epsg

GPKG_MAX_POINTS = 100_000
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
        raise InputError(f"{count} points are too many for a GeoPackage (at most {GPKG_MAX_POINTS}): write a "
                         ".laz or .las file, which QGIS shows as a point cloud")
    return ext


def output_srs(crs=None, lon=None, lat=None):
    """osr.SpatialReference (x = east / longitude first) of `crs` (EPSG code, 'EPSG:n', WKT, PROJ
    string or osr.SpatialReference), or of the UTM zone of the centre of (lon, lat)."""
    if crs is None or crs == "":
        finite = np.isfinite(lon) & np.isfinite(lat)
        if not finite.any():
            raise InputError("no point to choose the UTM zone from: give the output CRS")
        crs = utm_epsg(float(np.mean(lon[finite])), float(np.mean(lat[finite])))
    return parse_crs(crs)


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


def laspy_module():
    """laspy, imported quietly."""
    with warnings.catch_warnings():
        # laspy imports pyproj where installed, which warns about its data; the CRS goes through OSR here
        warnings.simplefilter("ignore", UserWarning)
        import laspy
    return laspy


def write_las(path, x, y, z, fields, srs, compress=False):
    """LAS 1.4 / point format 6 (LAZ when `compress`) with the WKT of `srs` and `fields` as extra bytes."""
    laspy = laspy_module()
    if compress and not laspy.LazBackend.detect_available():
        raise InputError("writing LAZ needs the lazrs or laszip Python package (pip install lazrs); "
                         "write a .las file instead")
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.global_encoding.wkt = True
    header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(srs.ExportToWkt()))
    header.generating_software = "Pushbroom (z: ellipsoidal h)"
    step = 1e-8 if srs.IsGeographic() else 1e-3
    header.scales = np.array([step, step, 1e-3])
    header.offsets = np.array([np.floor(v.min()) if v.size else 0.0 for v in (x, y, z)])
    header.add_extra_dims([laspy.ExtraBytesParams(name=name, type=values.dtype) for name, values in fields.items()])
    las = laspy.LasData(header)
    las.x, las.y, las.z = x, y, z
    for name, values in fields.items():
        las[name] = values
    with atomic_path(path) as tmp:
        las.write(tmp)
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
