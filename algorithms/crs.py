"""Coordinate reference systems through OSR/PROJ (all datum, CRS and geoid work goes
through PROJ): parsing a user's CRS, WGS 84, strict transformations and EGM96 undulations."""
import numpy as np
from osgeo import osr

from .errors import InputError

#: WGS 84 + EGM96 height (orthometric), transformed to EPSG:4979 for ellipsoidal heights
GEOID_CRS = "EPSG:4326+5773"


def srs(definition):
    """An osr.SpatialReference with x = east / longitude first (GIS order) from an EPSG code, 'EPSG:n',
    WKT, a PROJ string or an osr.SpatialReference (copied). Raises InputError if PROJ cannot read it."""
    if isinstance(definition, osr.SpatialReference):
        out = definition.Clone()
    else:
        out = osr.SpatialReference()
        text = f"EPSG:{definition}" if isinstance(definition, (int, np.integer)) else str(definition)
        try:
            failed = out.SetFromUserInput(text) != 0
        except RuntimeError:
            failed = True
        if failed:
            raise InputError(f"unknown coordinate reference system {text[:200]!r}: give an EPSG code or WKT")
    out.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return out


#: names GeoPackage gives the CRS of a layer written without one (srs_id 0 and -1)
UNDEFINED_NAMES = ("Undefined geographic SRS", "Undefined Cartesian SRS")


def is_undefined(definition):
    """Whether the osr.SpatialReference `definition` places nothing on Earth: a local (engineering) CRS
    or a GeoPackage's 'Undefined ... SRS'."""
    return bool(definition.IsLocal()) or definition.GetName() in UNDEFINED_NAMES


def wgs84():
    """WGS 84 geographic 2-D (EPSG:4326), longitude first."""
    return srs(4326)


#: points handed to PROJ at a time: osr takes Python lists, about 200 bytes a point
TRANSFORM_CHUNK = 65536


def transform(source, target, xyz, what):
    """Points (n, 2 or 3) from `source` to `target`, no ballpark operations (a missing grid is an
    error, not a silent metre-level shift); `what` names the points in the error message. TRANSFORM_CHUNK
    points at a time, so memory follows the chunk, not the points."""
    xyz = np.asarray(xyz, float)
    if not len(xyz):
        return xyz.reshape(0, xyz.shape[1] if xyz.ndim == 2 else 2)
    options = osr.CoordinateTransformationOptions()
    options.SetBallparkAllowed(False)
    try:
        ct = osr.CreateCoordinateTransformation(source, target, options)
    except RuntimeError:
        ct = None
    if ct is None:
        raise InputError(f"cannot transform {what} from {source.GetName()} to {target.GetName()}: PROJ knows no "
                         "transformation between them here (one of them is a local or undefined CRS, or the datum "
                         "shift grid it needs is not installed: install PROJ's grids with projsync or the proj-data "
                         "package), so give the data in another CRS")
    return np.concatenate([np.array(ct.TransformPoints(xyz[a:a + TRANSFORM_CHUNK].tolist()), float)
                           for a in range(0, len(xyz), TRANSFORM_CHUNK)]).reshape(len(xyz), -1)


def reproject(x, y, source, target, what="the points"):
    """(x, y) in `target` of points (x, y: 1-D arrays) in `source` (`transform`; the arrays as float where
    the CRSs are the same)."""
    if source.IsSame(target):
        return np.asarray(x, float), np.asarray(y, float)
    xy = transform(source, target, np.column_stack([x, y]), what)
    return xy[:, 0], xy[:, 1]


def egm96_undulation(lon, lat):
    """EGM96 geoid undulation N (m; h = H + N) at WGS 84 lon/lat (degrees, arrays of one shape):
    PROJ's EPSG:4326+5773 -> EPSG:4979 with its EGM96 grid. Raises InputError without the grid."""
    lon, lat = np.broadcast_arrays(np.asarray(lon, float), np.asarray(lat, float))
    points = np.column_stack([lon.ravel(), lat.ravel(), np.zeros(lon.size)])
    try:
        out = transform(srs(GEOID_CRS), srs(4979), points, "EGM96 heights")
    except InputError as exc:
        raise InputError(f"EGM96 heights need PROJ's EGM96 geoid grid (us_nga_egm96_15.tif or egm96_15.gtx), "
                         f"which is not available ({exc}): install it in a PROJ data folder "
                         f"({', '.join(osr.GetPROJSearchPaths() or [])}) or give ellipsoidal heights") from exc
    if not np.isfinite(out[:, 2]).all():
        raise InputError("the EGM96 geoid undulation could not be computed for every point: check the "
                         "coordinates and that PROJ's EGM96 grid (us_nga_egm96_15.tif) is installed")
    return out[:, 2].reshape(lon.shape)
