"""Reading point clouds and breaklines for the DEM: LAS/LAZ (laspy; the files pointcloud.py writes)
and any OGR vector layer of 3-D points (the GeoPackage point layer of pointcloud.py, a shapefile,
GeoJSON ...) or 3-D lines. z is taken as the WGS 84 ellipsoidal height (pointcloud.py's convention).

Failure modes, each an InputError in Pushbroom's words: a missing or unreadable file; a LAS/LAZ file cut
short (an interrupted copy or download: fewer bytes than its header's points need, a LAZ chunk table beyond
its end) or whose points do not decode (`damaged_error`); no CRS, or an undefined one (crs.is_undefined: no
CRS VLR in a LAS, a GeoPackage layer without SRS); coordinates that cannot be in their CRS
(check_coordinates: degrees labelled with a projected CRS, metres with a geographic one, points far outside
the CRS's area of use)."""

import os
import struct
from dataclasses import dataclass, field

import numpy as np
from osgeo import ogr

from ..crs import area_of_use, is_undefined, reproject, srs as parse_crs, transform, wgs84, within_area_of_use
from ..errors import InputError
from .pointcloud import laspy_module

#: LAS GeoTIFF keys holding an EPSG code: ProjectedCSTypeGeoKey, GeographicTypeGeoKey
EPSG_GEOKEYS = (3072, 2048)
#: in a projected CRS a satellite point cloud spans more than this (m); less, with values in the ranges
#: of longitude and latitude, means degrees labelled with a projected CRS
MIN_SPAN = 10.0


@dataclass
class PointSet:
    """Points (x, y in `srs`, z ellipsoidal m) and their numeric per-point fields (pointcloud.py's
    group, rho, sigma_h ...: {name: array})."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    srs: object
    fields: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.x)

    @property
    def sigma_h(self):
        """The a priori height sigma (m) where the file has one, else None."""
        return self.fields.get("sigma_h")

    def to(self, target):
        """The points with x, y transformed to `target` (osr.SpatialReference)."""
        if self.srs.IsSame(target):
            return self
        xy = transform(self.srs, target, np.column_stack([self.x, self.y]), "the point cloud")
        return PointSet(xy[:, 0], xy[:, 1], self.z, target, self.fields)


def no_crs_error(path, what, why, vector):
    """InputError: the `what` ('point cloud' or 'breaklines') `path` has no usable CRS (`why`): how to
    give one (a point cloud's CRS can also be given with the points: read_points(path, crs))."""
    assign = (
        f"ogr2ogr -a_srs EPSG:<code> out.gpkg {path}, or QGIS's 'Assign projection'"
        if vector
        else f"pdal translate {path} out.las --writers.las.a_srs=EPSG:<code>"
    )
    give = "give the CRS its x, y are in (the point cloud CRS parameter), or " if what == "point cloud" else ""
    return InputError(
        f"the {what} {path} has no coordinate reference system ({why}), so where it lies is unknown: "
        f"{give}assign the CRS to the file (e.g. {assign})"
    )


def _defined(srs, path, what, vector):
    """`srs` (osr.SpatialReference) unless it places nothing on Earth (crs.is_undefined)."""
    if is_undefined(srs):
        raise no_crs_error(
            path, what, f"its CRS '{srs.GetName()}' is a local or undefined one, not placed on Earth", vector
        )
    return srs


def las_srs(las, path):
    """The CRS of the LAS/LAZ file `path` (laspy reader or data `las`): its WKT VLR, else its EPSG GeoKey; InputError
    saying what to do where it has none."""
    laspy = laspy_module()
    for vlr in list(las.header.vlrs) + list(las.header.evlrs or []):
        if isinstance(vlr, laspy.vlrs.known.WktCoordinateSystemVlr):
            try:
                return _defined(parse_crs(vlr.string), path, "point cloud", False)
            except InputError as exc:
                if "unknown coordinate reference system" not in str(exc):
                    raise
                raise no_crs_error(path, "point cloud", "its WKT VLR holds no CRS PROJ reads", False) from None
        if isinstance(vlr, laspy.vlrs.known.GeoKeyDirectoryVlr):
            for key in vlr.geo_keys:
                if key.id in EPSG_GEOKEYS and 0 < key.value_offset < 32767:
                    return parse_crs(int(key.value_offset))
    raise no_crs_error(path, "point cloud", "no WKT or EPSG GeoKey VLR", False)


def damaged_error(path, why):
    """InputError: the LAS/LAZ file `path` is damaged (`why`), with what to do."""
    return InputError(
        f"the point cloud {path} is damaged: {why}. It was cut short or overwritten (an interrupted "
        "copy or download, a full disk): copy it again, or make it again (pushbroom:intersectpoints)"
    )


def _cut_short(path, header):
    """Why the LAS/LAZ file `path` with laspy `header` is cut short, or '': an uncompressed file holds fewer bytes
    than its points need; a LAZ file's chunk table (its offset: the first 8 bytes of the point data) lies
    beyond its end."""
    size = os.path.getsize(path)
    start, count = int(header.offset_to_point_data), int(header.point_count)
    if not header.are_points_compressed:
        need = start + count * int(header.point_format.size)
        return (
            f"its header announces {count} points, {need} bytes with the header, but the file holds {size} bytes"
            if size < need
            else ""
        )
    with open(path, "rb") as f:
        f.seek(start)
        table = f.read(8)
    offset = struct.unpack("<q", table)[0] if len(table) == 8 else size
    return (
        f"its compressed points end at byte {size}, before their chunk table at byte {offset}"
        if offset > size - 8
        else ""
    )


#: bytes of the smallest LAS public header block (LAS 1.0 - 1.2; 1.3 and 1.4 have more)
LAS_HEADER_BYTES = 227


def open_las(path):
    """laspy's reader of the LAS/LAZ file `path` (InputError where it cannot be read or is cut short)."""
    laspy = laspy_module()
    if not os.path.exists(path):
        raise InputError(f"cannot read the point cloud {path}: the file does not exist; check the path")
    if os.fspath(path).lower().endswith(".laz") and not laspy.LazBackend.detect_available():
        raise InputError(
            f"cannot read the point cloud {path}: reading LAZ needs the lazrs or laszip Python "
            "package (pip install lazrs), or convert the file to LAS"
        )
    with open(path, "rb") as f:
        head = f.read(LAS_HEADER_BYTES)
    if head.startswith(b"LASF") and len(head) < LAS_HEADER_BYTES:
        raise damaged_error(path, f"it holds {len(head)} bytes, less than a LAS header ({LAS_HEADER_BYTES})")
    try:
        reader = laspy.open(os.fspath(path))
    except Exception as exc:  # laspy raises its own and OS errors
        raise InputError(f"cannot read the point cloud {path}: not a LAS/LAZ file laspy reads ({exc})") from exc
    why = _cut_short(path, reader.header)
    if why:
        reader.close()
        raise damaged_error(path, why)
    return reader


def _las_chunks(path, crs, chunk=None):
    """PointSets of at most `chunk` points (None: all) of a LAS/LAZ file; one, empty, for an empty file."""
    with open_las(path) as reader:
        srs = parse_crs(crs) if crs else las_srs(reader, path)
        names = list(reader.header.point_format.extra_dimension_names)
        total = reader.header.point_count
        step = max(total, 1) if chunk is None else int(chunk)
        try:
            for _ in range(0, max(total, 1), step):
                records = reader.read_points(step)
                yield PointSet(
                    np.asarray(records.x, float),
                    np.asarray(records.y, float),
                    np.asarray(records.z, float),
                    srs,
                    {name: np.asarray(records[name]) for name in names},
                )
        except InputError:
            raise
        except Exception as exc:  # laspy and lazrs raise their own and OS errors
            raise damaged_error(path, f"its points cannot be read ({exc})") from exc


def read_las(path, crs=None):
    """PointSet of a LAS/LAZ file (fields: its extra dimensions)."""
    return next(_las_chunks(path, crs))


def point_count(path):
    """The number of points of a LAS/LAZ file (its header) or of an OGR point layer (`path|layername=...`),
    for the progress over point_chunks."""
    path, _, layer = os.fspath(path).partition("|layername=")
    if os.path.splitext(path)[1].lower() in (".las", ".laz"):
        with open_las(path) as reader:
            return int(reader.header.point_count)
    ds, lyr = _open_layer(path, layer or None, "point cloud")
    count = int(lyr.GetFeatureCount())
    del lyr, ds
    return count


def point_chunks(path, crs=None, chunk=1_000_000):
    """The points of `read_points` as PointSets of at most `chunk` points, read one at a time from a LAS/LAZ
    file (memory follows the chunk; an OGR layer is read as one chunk). Each chunk is checked as
    read_points checks the whole (check_coordinates)."""
    path, _, layer = os.fspath(path).partition("|layername=")
    if os.path.splitext(path)[1].lower() in (".las", ".laz"):
        chunks = _las_chunks(path, crs, chunk)
    else:
        chunks = iter([read_ogr_points(path, layer or None, crs)])
    for points in chunks:
        check_coordinates(points, path)
        yield points


def _open_layer(path, layer_name, what):
    ogr.UseExceptions()
    if not os.path.exists(path):
        raise InputError(f"cannot open the {what} {path}: the file does not exist; check the path")
    try:
        ds = ogr.Open(os.fspath(path))
    except RuntimeError as exc:
        raise InputError(f"cannot open the {what} {path}: {exc}") from exc
    if ds is None:
        raise InputError(f"cannot open the {what} {path}: not a file GDAL/OGR reads")
    layer = ds.GetLayerByName(layer_name) if layer_name else ds.GetLayer(0)
    if layer is None:
        raise InputError(f"{path} has no layer {layer_name or 0} of {what}")
    return ds, layer


def _layer_srs(layer, crs, path, what):
    if crs:
        return parse_crs(crs)
    if layer.GetSpatialRef() is None:
        raise no_crs_error(path, what, "its layer has none", True)
    return _defined(parse_crs(layer.GetSpatialRef()), path, what, True)


def read_ogr_points(path, layer_name=None, crs=None):
    """PointSet of an OGR layer of 3-D points (fields: its numeric attribute fields)."""
    ds, layer = _open_layer(path, layer_name, "points")
    if ogr.GT_Flatten(layer.GetGeomType()) not in (ogr.wkbPoint, ogr.wkbUnknown) or not ogr.GT_HasZ(
        layer.GetGeomType()
    ):
        raise InputError(f"{path} is not a layer of 3-D points: a point cloud needs points with z")
    defn = layer.GetLayerDefn()
    numeric = [
        defn.GetFieldDefn(k).GetName()
        for k in range(defn.GetFieldCount())
        if defn.GetFieldDefn(k).GetType() in (ogr.OFTInteger, ogr.OFTInteger64, ogr.OFTReal)
    ]
    xyz, values = [], {name: [] for name in numeric}
    for feature in layer:
        geometry = feature.GetGeometryRef()
        if geometry is not None and not geometry.IsEmpty():
            xyz.append(geometry.GetPoint())
            for name in numeric:
                values[name].append(np.nan if feature[name] is None else feature[name])
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    srs = _layer_srs(layer, crs, path, "point cloud")
    del ds
    return PointSet(xyz[:, 0], xyz[:, 1], xyz[:, 2], srs, {k: np.asarray(v, float) for k, v in values.items()})


def check_coordinates(points, path):
    """InputError where the points' x, y cannot be coordinates in their CRS: outside the ranges of
    longitude and latitude in a geographic CRS; in a projected CRS, within MIN_SPAN metres with values
    in those ranges (degrees labelled as metres); their centre more than crs.AREA_MARGIN degrees outside the
    CRS's area of use (or not placeable on Earth at all)."""
    ok = np.isfinite(points.x) & np.isfinite(points.y)
    if not ok.any():
        return
    x, y = points.x[ok], points.y[ok]
    box = f"x {x.min():.8g} .. {x.max():.8g}, y {y.min():.8g} .. {y.max():.8g}"
    name = points.srs.GetName()
    degrees = x.min() >= -180.0 and x.max() <= 360.0 and y.min() >= -90.0 and y.max() <= 90.0
    if points.srs.IsGeographic() and not degrees:
        raise InputError(
            f"the point cloud {path} has coordinates {box}, which are not longitude/latitude degrees, "
            f"but its CRS {name} is geographic: are they projected metres? Give the point cloud the CRS "
            "its coordinates are in"
        )
    span = max(np.ptp(x), np.ptp(y)) * points.srs.GetLinearUnits()
    if points.srs.IsProjected() and 0.0 < span < MIN_SPAN and degrees:
        raise InputError(
            f"the point cloud {path} spans only {span:.3g} m in its CRS {name} ({box}): these look like "
            "longitude/latitude degrees labelled with a projected CRS. Give the point cloud the CRS its "
            "coordinates are in (EPSG:4326 for degrees)"
        )
    lon, lat = reproject(
        np.array([np.mean(x)]), np.array([np.mean(y)]), points.srs, wgs84(), "the point cloud's centre"
    )
    if not within_area_of_use(points.srs, float(lon[0]), float(lat[0])):
        where = (
            f"at longitude {lon[0]:.4f}, latitude {lat[0]:.4f}"
            if np.isfinite(lon[0]) and np.isfinite(lat[0])
            else "nowhere on Earth (outside what the CRS's projection covers)"
        )
        raise InputError(
            f"the point cloud {path} ({box}) lies {where} according to its CRS {name}, far from where "
            f"that CRS is used ({area_of_use(points.srs)}): the file's CRS is not the one of its "
            "coordinates (x and y swapped?). Give the point cloud the CRS its coordinates are in"
        )


def read_points(path, crs=None):
    """PointSet of a LAS/LAZ file or an OGR point layer (`path` or 'path|layername=name'); `crs`
    overrides the file's CRS. InputError where the coordinates cannot be in that CRS (check_coordinates)."""
    path, _, layer = os.fspath(path).partition("|layername=")
    if os.path.splitext(path)[1].lower() in (".las", ".laz"):
        points = read_las(path, crs)
    else:
        points = read_ogr_points(path, layer or None, crs)
    check_coordinates(points, path)
    return points


def read_breaklines(path, layer_name=None):
    """3-D breaklines of an OGR line layer: (list of (n, 3) arrays, the layer's osr.SpatialReference)."""
    ds, layer = _open_layer(path, layer_name, "breaklines")
    srs = _layer_srs(layer, None, path, "breaklines")
    lines = []
    for feature in layer:
        geometry = feature.GetGeometryRef()
        if geometry is None:
            continue
        if not geometry.Is3D():
            raise InputError(f"the breaklines of {path} have no z: breaklines need 3-D lines (heights)")
        parts = (
            [geometry.GetGeometryRef(k) for k in range(geometry.GetGeometryCount())]
            if geometry.GetGeometryCount()
            else [geometry]
        )
        for part in parts:
            xyz = np.asarray(part.GetPoints() or [], float).reshape(-1, 3)
            if len(xyz) >= 2:
                lines.append(xyz)
    del ds
    return lines, srs
