"""Reading object points back: the LAS/LAZ files and GeoPackage point layers of
surface/pointcloud.py (x, y in the file's CRS, z the height, per-point fields such as group), or
any OGR point layer with z."""
import os

import numpy as np
from osgeo import ogr

from ..crs import srs as parse_crs
from ..errors import InputError
from ..surface.pointcloud import GPKG_LAYER, _laspy


def read_point_cloud(path):
    """(x, y, z, srs, fields {name: array}) of the points of a .las/.laz file or an OGR point layer."""
    path = os.fspath(path)
    if not os.path.exists(path.split("|")[0]):
        raise InputError(f"point cloud {path} does not exist")
    if path.lower().endswith((".las", ".laz")):
        return _read_las(path)
    return _read_ogr(path)


def _read_las(path):
    laspy = _laspy()
    try:
        las = laspy.read(path)
    except Exception as exc:  # laspy raises its own and OS errors for damaged or LAZ-without-backend files
        raise InputError(f"cannot read the point cloud {path}: {exc}") from exc
    wkt = [v.string for v in las.header.vlrs if isinstance(v, laspy.vlrs.known.WktCoordinateSystemVlr)]
    if not wkt:
        raise InputError(f"the point cloud {path} has no OGC WKT coordinate system record: write it with "
                         "pushbroom:intersectpoints or assign a CRS (e.g. with PDAL)")
    fields = {name: np.asarray(las[name]) for name in las.point_format.extra_dimension_names}
    return (np.asarray(las.x, float), np.asarray(las.y, float), np.asarray(las.z, float), parse_crs(wkt[0]),
            fields)


def _read_ogr(path):
    ogr.UseExceptions()
    name, _, layer_name = path.partition("|layername=")
    try:
        ds = ogr.Open(name)
    except RuntimeError as exc:
        raise InputError(f"cannot open the point cloud {path}: {exc}") from exc
    layer = ds.GetLayerByName(layer_name or GPKG_LAYER) or ds.GetLayer(0)
    srs = layer.GetSpatialRef()
    if srs is None:
        raise InputError(f"the point layer {path} has no coordinate reference system")
    defn = layer.GetLayerDefn()
    names = [defn.GetFieldDefn(k).GetName() for k in range(defn.GetFieldCount())]
    xyz, values = [], {n: [] for n in names}
    for feature in layer:
        geom = feature.GetGeometryRef()
        if geom is None or geom.IsEmpty():
            continue
        point = geom.GetPoint(0) if geom.GetGeometryCount() == 0 else geom.GetGeometryRef(0).GetPoint(0)
        xyz.append(point)
        for n in names:
            values[n].append(feature[n])
    if not ogr.GT_HasZ(layer.GetGeomType()):
        raise InputError(f"the point layer {path} has no z: the assessment needs 3-D points")
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    fields = {}
    for n, v in values.items():
        try:
            fields[n] = np.asarray(v, float)
        except (TypeError, ValueError):
            continue  # text fields carry nothing the statistics use
    return xyz[:, 0], xyz[:, 1], xyz[:, 2], parse_crs(srs), fields
