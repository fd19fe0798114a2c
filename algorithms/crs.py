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


#: points handed to PROJ at a time: osr returns Python tuples, about 200 bytes a point
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
        raise InputError(
            f"cannot transform {what} from {source.GetName()} to {target.GetName()}: PROJ knows no "
            "transformation between them here (one of them is a local or undefined CRS, or the datum "
            "shift grid it needs is not installed: install PROJ's grids with projsync or the proj-data "
            "package), so give the data in another CRS"
        )
    return np.concatenate(
        [
            np.array(ct.TransformPoints(np.ascontiguousarray(xyz[a : a + TRANSFORM_CHUNK])), float)
            for a in range(0, len(xyz), TRANSFORM_CHUNK)
        ]
    ).reshape(len(xyz), -1)


def reproject(x, y, source, target, what="the points"):
    """(x, y) in `target` of points (x, y: 1-D arrays) in `source` (`transform`; the arrays as float where
    the CRSs are the same)."""
    if source.IsSame(target):
        return np.asarray(x, float), np.asarray(y, float)
    xy = transform(source, target, np.column_stack([x, y]), what)
    return xy[:, 0], xy[:, 1]


#: undulation lattice nodes per axis (at most): N varies over tens of kilometres
UNDULATION_NODES = 257


def undulation_rows(shape, geotransform, grid_srs=None):
    """rows -> EGM96 undulation N of those rows' cell centres of a north-up grid of `shape` (rows, cols) and
    `geotransform` in `grid_srs` (None: WGS 84 longitude/latitude): exact (egm96_undulation) on a lattice of at most
    UNDULATION_NODES per axis, bilinear between, so that a grid costs PROJ a lattice, not a call per cell."""
    from scipy.interpolate import RegularGridInterpolator

    rows, cols = shape
    x0, dx, _, y0, _, dy = geotransform
    r = np.unique(np.linspace(0, rows - 1, min(rows, UNDULATION_NODES)).round())
    c = np.unique(np.linspace(0, cols - 1, min(cols, UNDULATION_NODES)).round())
    x, y = np.meshgrid(x0 + (c + 0.5) * dx, y0 + (r + 0.5) * dy)
    if grid_srs is not None:
        x, y = reproject(x.ravel(), y.ravel(), grid_srs, wgs84(), "the grid's cells")
    lattice = RegularGridInterpolator((r, c), egm96_undulation(x, y).reshape(len(r), len(c)))

    def at(first, count):
        rr, cc = np.mgrid[first : first + count, 0:cols]
        return lattice(np.column_stack([rr.ravel(), cc.ravel()])).reshape(count, cols)

    return at


def egm96_undulation(lon, lat):
    """EGM96 geoid undulation N (m; h = H + N) at WGS 84 lon/lat (degrees, arrays of one shape):
    PROJ's EPSG:4326+5773 -> EPSG:4979 with its EGM96 grid. Raises InputError without the grid."""
    lon, lat = np.broadcast_arrays(np.asarray(lon, float), np.asarray(lat, float))
    points = np.column_stack([lon.ravel(), lat.ravel(), np.zeros(lon.size)])
    try:
        out = transform(srs(GEOID_CRS), srs(4979), points, "EGM96 heights")
    except InputError as exc:
        raise InputError(
            f"EGM96 heights need PROJ's EGM96 geoid grid (us_nga_egm96_15.tif or egm96_15.gtx), "
            f"which is not available ({exc}): install it in a PROJ data folder "
            f"({', '.join(osr.GetPROJSearchPaths() or [])}) or give ellipsoidal heights"
        ) from exc
    if not np.isfinite(out[:, 2]).all():
        raise InputError(
            "the EGM96 geoid undulation could not be computed for every point: check the "
            "coordinates and that PROJ's EGM96 grid (us_nga_egm96_15.tif) is installed"
        )
    return out[:, 2].reshape(lon.shape)


#: degrees data may lie beyond the area of use of a CRS (a scene across a UTM zone border, a country mapped in one
#: zone: transverse Mercator stays usable several degrees beyond its zone); farther, the CRS is not the data's
AREA_MARGIN = 10.0


def area_of_use(target):
    """'longitude w .. e, latitude s .. n' of the area of use of the osr.SpatialReference `target`."""
    area = target.GetAreaOfUse()
    return (
        f"longitude {area.west_lon_degree:g} .. {area.east_lon_degree:g}, latitude {area.south_lat_degree:g} .. "
        f"{area.north_lat_degree:g}"
    )


def within_area_of_use(target, lon, lat):
    """Whether (lon, lat) (degrees) lies within AREA_MARGIN degrees of the area of use PROJ gives for `target`
    (True where the CRS has none, False where lon or lat is not finite). Longitudes are compared around the
    globe, so an area across the antimeridian holds the points on either side of it."""
    area = target.GetAreaOfUse()
    if area is None:
        return True
    if not (np.isfinite(lon) and np.isfinite(lat)):
        return False
    span = (area.east_lon_degree - area.west_lon_degree) % 360.0 or 360.0  # an area across the antimeridian too
    beyond = (lon - area.west_lon_degree) % 360.0 - span  # > 0: east of the area, by this much
    outside = 0.0 if beyond <= 0.0 else min(beyond, 360.0 - span - beyond)
    return outside <= AREA_MARGIN and area.south_lat_degree - AREA_MARGIN <= lat <= area.north_lat_degree + AREA_MARGIN


def check_output_crs(target, lon, lat, what):
    """InputError where the output CRS `target` (osr.SpatialReference) is used far from `what` ("the point
    cloud"), whose centre is at (lon, lat) degrees (within_area_of_use): a projection far from its area of use
    mirrors or tears the data (a UTM zone 200 degrees away puts a scene at a northing of 15 000 km)."""
    if not within_area_of_use(target, float(lon), float(lat)):
        raise InputError(
            f"the output CRS {target.GetName()} is used at {area_of_use(target)}, far from {what} "
            f"(longitude {lon:.4f}, latitude {lat:.4f}): choose an output CRS used there, or leave it "
            "empty for the UTM zone there"
        )


#: cells a grid has at least along each axis: fewer is no raster of the data (one cell, one value)
MIN_CELLS = 2
#: cells a grid has at most (GDAL's and the tiles' 32-bit counts): more is a cell size in the wrong unit
MAX_CELLS = 2**31


def unit_name(target):
    """The unit of the x/y coordinates of `target` (osr.SpatialReference): 'degrees', 'metres', 'US survey feet' ..."""
    if target.IsGeographic():
        return "degrees"
    name = target.GetLinearUnitsName() or "units"
    return "metres" if name.lower() in ("metre", "meter", "m") else name


def cell_unit_hint(cell, target):
    """A sentence where the cell size `cell` looks given in another unit than the CRS `target`'s (a cell of
    metres in a degree CRS: over 0.1 degree, 11 km; a cell of degrees in a metre CRS: under 1 cm), else ''."""
    if target.IsGeographic() and cell > 0.1:
        return (
            " The CRS's unit is the degree: is the cell size in metres? (10 m is about 0.00009 degrees, a "
            "projected CRS such as the UTM zone takes metres)"
        )
    if target.IsProjected() and cell * target.GetLinearUnits() < 0.01:
        return f" The CRS's unit is {unit_name(target)}: is the cell size in degrees?"
    return ""


def check_grid_cells(cols, rows, cell, target, extent, what):
    """InputError where a grid of `cols` x `rows` cells of `cell` units of the CRS `target` over `extent`
    (width, height in those units) has fewer than MIN_CELLS along an axis, or more than MAX_CELLS: `what` names it
    ("the orthoimage")."""
    unit = unit_name(target)
    if cols * rows > MAX_CELLS:
        raise InputError(
            f"a cell size of {cell:g} {unit} makes {what} a grid of {cols} x {rows} cells, too many: give "
            f"a larger cell size.{cell_unit_hint(cell, target)}"
        )
    if min(cols, rows) >= MIN_CELLS:
        return
    if min(extent) <= 0:
        raise InputError(
            f"the data span {extent[0]:.4g} x {extent[1]:.4g} {unit} ({target.GetName()}), no area: "
            f"{what} needs data spread over at least {MIN_CELLS} x {MIN_CELLS} cells"
        )
    raise InputError(
        f"a cell size of {cell:g} {unit} makes {what} a grid of {cols} x {rows} cells over "
        f"{extent[0]:.4g} x {extent[1]:.4g} {unit} ({target.GetName()}): give a cell size of at most "
        f"{min(extent) / MIN_CELLS:.4g} {unit}.{cell_unit_hint(cell, target)}"
    )
