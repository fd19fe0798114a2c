"""Reading point clouds and breaklines for the DEM: LAS/LAZ (laspy; the files pointcloud.py writes)
and any OGR vector layer of 3-D points (the GeoPackage point layer of pointcloud.py, a shapefile,
GeoJSON ...) or 3-D lines. z is taken as the WGS 84 ellipsoidal height (pointcloud.py's convention)."""
import os
from dataclasses import dataclass, field

import numpy as np
from osgeo import ogr

from ..crs import srs as parse_crs, transform
from ..errors import InputError
from .pointcloud import laspy_module

#: LAS GeoTIFF keys holding an EPSG code: ProjectedCSTypeGeoKey, GeographicTypeGeoKey
EPSG_GEOKEYS = (3072, 2048)


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


def _las_srs(las, path):
    laspy = laspy_module()
    for vlr in list(las.header.vlrs) + list(las.header.evlrs or []):
        if isinstance(vlr, laspy.vlrs.known.WktCoordinateSystemVlr):
            return parse_crs(vlr.string)
        if isinstance(vlr, laspy.vlrs.known.GeoKeyDirectoryVlr):
            for key in vlr.geo_keys:
                if key.id in EPSG_GEOKEYS and 0 < key.value_offset < 32767:
                    return parse_crs(int(key.value_offset))
    raise InputError(f"{path} has no coordinate reference system (no WKT or EPSG GeoKey VLR): give the CRS")


def read_las(path, crs=None):
    """PointSet of a LAS/LAZ file (fields: its extra dimensions)."""
    laspy = laspy_module()
    try:
        las = laspy.read(os.fspath(path))
    except Exception as exc:  # laspy raises its own and OS errors
        raise InputError(f"cannot read the point cloud {path}: {exc}") from exc
    srs = parse_crs(crs) if crs else _las_srs(las, path)
    fields = {name: np.asarray(las[name]) for name in las.point_format.extra_dimension_names}
    return PointSet(np.asarray(las.x, float), np.asarray(las.y, float), np.asarray(las.z, float), srs, fields)


def _open_layer(path, layer_name, what):
    ogr.UseExceptions()
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


def _layer_srs(layer, crs, path):
    if crs:
        return parse_crs(crs)
    if layer.GetSpatialRef() is None:
        raise InputError(f"{path} has no coordinate reference system: give the CRS")
    return parse_crs(layer.GetSpatialRef())


def read_ogr_points(path, layer_name=None, crs=None):
    """PointSet of an OGR layer of 3-D points (fields: its numeric attribute fields)."""
    ds, layer = _open_layer(path, layer_name, "points")
    if ogr.GT_Flatten(layer.GetGeomType()) not in (ogr.wkbPoint, ogr.wkbUnknown) or not ogr.GT_HasZ(
            layer.GetGeomType()):
        raise InputError(f"{path} is not a layer of 3-D points: a point cloud needs points with z")
    defn = layer.GetLayerDefn()
    numeric = [defn.GetFieldDefn(k).GetName() for k in range(defn.GetFieldCount())
               if defn.GetFieldDefn(k).GetType() in (ogr.OFTInteger, ogr.OFTInteger64, ogr.OFTReal)]
    xyz, values = [], {name: [] for name in numeric}
    for feature in layer:
        geometry = feature.GetGeometryRef()
        if geometry is not None and not geometry.IsEmpty():
            xyz.append(geometry.GetPoint())
            for name in numeric:
                values[name].append(np.nan if feature[name] is None else feature[name])
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    srs = _layer_srs(layer, crs, path)
    ds = None
    return PointSet(xyz[:, 0], xyz[:, 1], xyz[:, 2], srs, {k: np.asarray(v, float) for k, v in values.items()})


def read_points(path, crs=None):
    """PointSet of a LAS/LAZ file or an OGR point layer (`path` or 'path|layername=name'); `crs`
    overrides the file's CRS."""
    path, _, layer = os.fspath(path).partition("|layername=")
    if os.path.splitext(path)[1].lower() in (".las", ".laz"):
        return read_las(path, crs)
    return read_ogr_points(path, layer or None, crs)


def read_breaklines(path, layer_name=None):
    """3-D breaklines of an OGR line layer: (list of (n, 3) arrays, the layer's osr.SpatialReference)."""
    ds, layer = _open_layer(path, layer_name, "breaklines")
    srs = _layer_srs(layer, None, path)
    lines = []
    for feature in layer:
        geometry = feature.GetGeometryRef()
        if geometry is None:
            continue
        if not geometry.Is3D():
            raise InputError(f"the breaklines of {path} have no z: breaklines need 3-D lines (heights)")
        parts = [geometry.GetGeometryRef(k) for k in range(geometry.GetGeometryCount())] \
            if geometry.GetGeometryCount() else [geometry]
        for part in parts:
            xyz = np.asarray(part.GetPoints() or [], float).reshape(-1, 3)
            if len(xyz) >= 2:
                lines.append(xyz)
    ds = None
    return lines, srs
