"""Classes of the assessed points and cells (Zhang and Gruen 2004, section 4.2: open / city / trees / alpine;
Kornus et al. 2006, section 3.7: flat vs mountainous): from a class raster (e.g. the simulator's classes.tif,
names in its CLASS_<n> metadata or the band's category names), from polygons with a class field, or from the
slope of the reference. Class 0 (and the raster's nodata) means "no class".

A class raster holds class codes: whole numbers (an integer data type, or floats that are all whole), at most
MAX_CLASSES of them. Anything else (a DSM given as classes: every height a "class") is an InputError."""

import numpy as np
from matplotlib.path import Path
from osgeo import gdal, ogr

from ..crs import reproject, srs as parse_crs
from ..errors import InputError
from .rasters import by_blocks, cell_metres, open_raster, raster_srs, warp_to

NO_CLASS = 0
FLAT, MOUNTAINOUS = 1, 2
#: rows of a class raster read at a time for its class values
BAND_ROWS = 512
#: distinct classes a class raster may hold (land-cover maps hold tens: CORINE 44, ESA WorldCover 11)
MAX_CLASSES = 100


def slope_classes(slope, threshold):
    """FLAT where slope < threshold (degrees), MOUNTAINOUS where >=, NO_CLASS where NaN; and the names."""
    slope = np.asarray(slope, float)
    labels = np.where(slope < threshold, FLAT, np.where(slope >= threshold, MOUNTAINOUS, NO_CLASS))
    return labels, {
        FLAT: f"flat/moderate (slope < {threshold:g} deg)",
        MOUNTAINOUS: f"mountainous (>= {threshold:g} deg)",
    }


class ClassRaster:
    """Integer classes of a raster; `names` {value: name}. The file is opened per use: no GDAL
    dataset outlives a call (one freed after QGIS has exited crashes the interpreter)."""

    def __init__(self, path):
        self.path = str(path)
        ds = self._open()
        band = ds.GetRasterBand(1)
        self.nodata = band.GetNoDataValue()
        meta = ds.GetMetadata() or {}
        values = np.unique(
            np.concatenate(
                [
                    np.unique(band.ReadAsArray(0, r0, ds.RasterXSize, min(BAND_ROWS, ds.RasterYSize - r0)))
                    for r0 in range(0, ds.RasterYSize, BAND_ROWS)
                ]
            )
        )
        values = values[np.isfinite(values) & (values != NO_CLASS)]
        if self.nodata is not None:
            values = values[values != self.nodata]
        self._check(values, gdal.GetDataTypeName(band.DataType))
        categories = band.GetCategoryNames() or []
        self.names = {}
        for v in values.tolist():
            v = int(v)
            name = meta.get(f"CLASS_{v}") or (categories[v] if v < len(categories) and categories[v] else None)
            self.names[v] = name or f"class {v}"

    def _check(self, values, kind):
        """InputError unless the class `values` (unique, without nodata and NO_CLASS) of a raster of GDAL data
        type `kind` are class codes (module docstring)."""
        fractional = values[values != np.round(values)]
        if fractional.size or values.size > MAX_CLASSES:
            example = f"such as {fractional[0]:g}" if fractional.size else f"{values[0]:g} .. {values[-1]:g}"
            raise InputError(
                f"the class raster {self.path} holds {values.size} distinct values ({kind}, {example}), "
                f"not class codes: a class raster holds whole numbers, at most {MAX_CLASSES} classes "
                "(a land-cover map such as the simulator's classes.tif). Is it a height raster? Give "
                "the classes, or leave the class raster empty"
            )

    def _open(self):
        return open_raster(self.path, "class raster")

    def at_points(self, x, y, srs):
        """Class of the cell holding each point (x, y in `srs`); NO_CLASS outside or on nodata. The raster is
        read by the window of each block of its cells that holds points (rasters.by_blocks)."""
        ds = self._open()
        xr, yr = reproject(x, y, srs, raster_srs(ds))
        x0, dx, _, y0, _, dy = ds.GetGeoTransform()
        c, r = np.floor((xr - x0) / dx), np.floor((yr - y0) / dy)
        inside = (c >= 0) & (r >= 0) & (c < ds.RasterXSize) & (r < ds.RasterYSize)
        out = np.full(len(xr), NO_CLASS, np.int64)
        for index in by_blocks(ds, xr, yr):
            index = index[inside[index]]
            if not index.size:
                continue
            ci, ri = c[index].astype(int), r[index].astype(int)
            window = ds.GetRasterBand(1).ReadAsArray(
                int(ci.min()), int(ri.min()), int(ci.max() - ci.min() + 1), int(ri.max() - ri.min() + 1)
            )
            out[index] = window[ri - ri.min(), ci - ci.min()]
        return self._clean(out)

    def on_grid(self, grid):
        """Classes on `grid`'s cells: the most frequent class of the cells inside (gdalwarp mode) where the
        class raster is finer, else the class at the cell (nearest)."""
        ds = self._open()
        own = cell_metres(ds.GetGeoTransform(), raster_srs(ds), ds.RasterYSize)
        finer = np.prod(own) < np.prod(grid.cell_metres())
        values = warp_to(ds, grid, "mode" if finer else "near")
        return self._clean(np.nan_to_num(values, nan=NO_CLASS).astype(np.int64))

    def _clean(self, labels):
        labels[~np.isin(labels, list(self.names))] = NO_CLASS
        return labels


class PolygonClasses:
    """Classes of polygons: `geometries` (OGR geometries or WKB), one class value per polygon (text or
    number) in `values`, CRS `crs`. Classes are numbered 1.. in the sorted order of the values; a point
    takes the class of the last polygon that holds it (holes excluded)."""

    def __init__(self, geometries, values, crs):
        self.srs = parse_crs(crs)
        self.geometries = [
            g if isinstance(g, ogr.Geometry) else ogr.CreateGeometryFromWkb(bytes(g)) for g in geometries
        ]
        values = [str(v) for v in values]
        if len(values) != len(self.geometries):
            raise InputError("the class polygons need one class value each")
        if not values:
            raise InputError("the class layer has no polygon")
        self.names = {k + 1: v for k, v in enumerate(sorted(set(values)))}
        code = {v: k for k, v in self.names.items()}
        self.codes = [code[v] for v in values]

    @classmethod
    def from_file(cls, path, field, layer=None):
        """The polygons of an OGR layer (first layer unless named) and their `field` values."""
        ogr.UseExceptions()
        try:
            ds = ogr.Open(str(path))
        except RuntimeError as exc:
            raise InputError(f"cannot open the class layer {path}: {exc}") from exc
        lyr = ds.GetLayerByName(layer) if layer else ds.GetLayer(0)
        if lyr.GetLayerDefn().GetFieldIndex(field) < 0:
            raise InputError(f"the class layer {path} has no field {field!r}")
        geometries, values = [], []
        for feature in lyr:
            if feature.GetGeometryRef() is not None:
                geometries.append(feature.GetGeometryRef().Clone())
                values.append(feature[field])
        return cls(geometries, values, lyr.GetSpatialRef() or "EPSG:4326")

    def at_points(self, x, y, srs):
        """Class of each point (x, y in `srs`), NO_CLASS outside every polygon."""
        xr, yr = reproject(x, y, srs, self.srs)
        xy = np.column_stack([xr, yr])
        out = np.full(len(xr), NO_CLASS, np.int64)
        for geom, code in zip(self.geometries, self.codes):
            for polygon in _polygons(geom):
                x0, x1, y0, y1 = polygon.GetEnvelope()
                near = np.flatnonzero((xr >= x0) & (xr <= x1) & (yr >= y0) & (yr <= y1))
                if not near.size:
                    continue
                inside = _ring_path(polygon.GetGeometryRef(0)).contains_points(xy[near])
                for k in range(1, polygon.GetGeometryCount()):
                    inside &= ~_ring_path(polygon.GetGeometryRef(k)).contains_points(xy[near])
                out[near[inside]] = code
        return out

    def on_grid(self, grid):
        """Class of each cell centre of `grid`."""
        x, y = grid.centres()
        return self.at_points(x.ravel(), y.ravel(), grid.srs).reshape(grid.shape)


def _polygons(geom):
    flat = ogr.GT_Flatten(geom.GetGeometryType())
    if flat == ogr.wkbPolygon:
        return [geom]
    if flat == ogr.wkbMultiPolygon:
        return [geom.GetGeometryRef(k) for k in range(geom.GetGeometryCount())]
    raise InputError(f"class layers hold polygons, not {geom.GetGeometryName()}")


def _ring_path(ring):
    return Path(np.asarray(ring.GetPoints(), float)[:, :2])
