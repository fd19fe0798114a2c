"""Height differences dh = assessed height - reference height (m, both ellipsoidal WGS 84) of object
points and of DEM cells against a reference DTM/DSM raster in any CRS (Kornus et al. 2006, section 3.6-3.7,
Zhang and Gruen 2004, section 4.2-4.3).

Points: the reference is interpolated bilinearly between its cell centres at each point, in the
reference's own CRS (the points are transformed to it; dem.Dem.height on the window of cells
around the points), NaN next to nodata. DEM cells: the reference is resampled onto the DEM's grid
and CRS with gdalwarp: the average of the reference cells inside a DEM cell where the reference is
finer, bilinear otherwise. Vertical datum per input: "ellipsoidal" or "orthometric" (EGM96:
h = H + N, adjustment.control_points.orthometric_to_ellipsoidal). The slope (Kornus et al. 2006, section 3.7:
flat/moderate vs mountainous) is the reference's (rasters.slope_degrees): at the points, or on the DEM grid.

The reference is read by the window of its cells under the assessed data, its nodata and a declared
void value (`reference_nodata`) as NaN; implausible heights among those cells (dem.implausible_heights,
such as SRTM voids not flagged as nodata) are reported as a warning (progress.warn) and used as given."""
from dataclasses import dataclass, field

import numpy as np

from .. import progress
from ..adjustment.control_points import HEIGHT_TYPES, orthometric_to_ellipsoidal
from ..crs import reproject, wgs84
from ..dem import Dem, implausible_heights
from ..errors import InputError
from ..surface.geotiff import write_float_raster
from ..surface.point_input import read_points
from .rasters import (
    Grid,
    cell_metres,
    memory_dataset,
    open_raster,
    outline,
    raster_srs,
    read_grid,
    read_window,
    slope_degrees,
    warp_to,
)


@dataclass
class Differences:
    """dh of the assessed points or cells that have a reference height, with where they are."""

    what: str                   # "object points" or "DEM cells"
    source: str                 # the assessed file
    dh: np.ndarray              # (n,) m
    x: np.ndarray               # (n,) position in `srs` (the assessed data's CRS)
    y: np.ndarray
    srs: object
    slope: np.ndarray           # (n,) degrees, of the reference
    group: np.ndarray = None    # (n,) point group 1/2/3 where the point cloud has one
    grid: Grid = None           # DEM input: the dh grid (NaN where undefined)
    valid: np.ndarray = None    # DEM input: the grid cells in dh
    excluded: dict = field(default_factory=dict)   # {reason: count} of left-out points or cells


def _check_datum(datum, what):
    if datum not in HEIGHT_TYPES:
        raise InputError(f"the heights of the {what} must be one of {', '.join(HEIGHT_TYPES)}, not {datum!r}")


def _ellipsoidal(h, x, y, srs, datum):
    """Heights h at points (x, y in srs) made ellipsoidal (EGM96 -> + N) where finite."""
    h = np.array(h, float)
    ok = np.isfinite(h)
    if datum == "orthometric" and ok.any():
        lon, lat = reproject(x[ok], y[ok], srs, wgs84())
        h[ok] = orthometric_to_ellipsoidal(lon, lat, h[ok])
    return h


def _reference_window(ds, reference, x, y, nodata, feedback):
    """The reference cells around points (x, y in its CRS) as a Grid (rasters.read_window, `nodata` a
    declared void value), with a warning about implausible heights among them."""
    window = read_window(ds, x, y, "reference DEM", nodata=nodata)
    progress.warn(feedback, implausible_heights(window.values, f"the reference DEM {reference}"))
    return window


def reference_at_points(reference, x, y, srs, datum="ellipsoidal", nodata=None, feedback=None):
    """(ellipsoidal reference height, reference slope in degrees) at points (x, y in `srs`): bilinear in
    the reference's CRS; NaN outside it and next to its nodata (and cells equal to `nodata`, a declared
    void value). InputError when it does not overlap; a warning (`feedback`) about implausible heights."""
    _check_datum(datum, "reference")
    ds = open_raster(reference, "reference DEM")
    xr, yr = reproject(x, y, srs, raster_srs(ds))
    window = _reference_window(ds, reference, xr, yr, nodata, feedback)
    if np.isnan(window.values).all():
        raise InputError(f"the reference DEM {reference} has only nodata where the assessed data are: choose a "
                         "reference that covers them")
    href = Dem(window.values, window.geotransform).height(xr, yr)
    slope = Dem(slope_degrees(window), window.geotransform).height(xr, yr)
    if not np.isfinite(href).any():
        raise InputError(f"the reference DEM {reference} does not overlap the assessed points: choose a reference "
                         "that covers them")
    return _ellipsoidal(href, x, y, srs, datum), slope


def point_differences(path, reference, reference_datum="ellipsoidal", points_datum="ellipsoidal", feedback=None,
                      reference_nodata=None):
    """Differences of the object points of a point cloud (surface.point_input.read_points) against
    the reference raster (`reference_nodata`: a declared void value); its `group` field, where present,
    is kept."""
    _check_datum(points_datum, "points")
    cloud = read_points(path)
    x, y, z, srs, fields = cloud.x, cloud.y, cloud.z, cloud.srs, cloud.fields
    if not len(x):
        raise InputError(f"the point cloud {path} holds no point")
    progress.step(feedback, 10, f"{len(x)} points read from {path}")
    href, slope = reference_at_points(reference, x, y, srs, reference_datum, reference_nodata, feedback)
    progress.step(feedback, 60)
    h = _ellipsoidal(z, x, y, srs, points_datum)
    ok = np.isfinite(h) & np.isfinite(href)
    group = fields.get("group")
    return Differences("object points", str(path), (h - href)[ok], x[ok], y[ok], srs, slope[ok],
                       None if group is None else np.asarray(group)[ok].astype(np.int64),
                       excluded={"outside the reference or next to its nodata": int((~ok).sum())})


def dem_differences(path, reference, reference_datum="ellipsoidal", dem_datum="ellipsoidal", feedback=None,
                    reference_nodata=None):
    """Differences of the cells of a DEM raster against the reference raster (`reference_nodata`: a
    declared void value) resampled onto its grid: the reference's window under the DEM, warped."""
    _check_datum(dem_datum, "DEM")
    _check_datum(reference_datum, "reference")
    dem = read_grid(open_raster(path, "DEM"))
    defined = np.isfinite(dem.values)
    if not defined.any():
        raise InputError(f"the DEM {path} holds no valid height (all cells are nodata)")
    progress.step(feedback, 10, f"DEM {path}: {dem.shape[1]} x {dem.shape[0]} cells, {int(defined.sum())} "
                                "with a height")
    ds = open_raster(reference, "reference DEM")
    no_overlap = InputError(f"the reference DEM {reference} does not overlap the DEM {path} (or holds only nodata "
                            "there): choose a reference that covers it")
    try:
        window = _reference_window(ds, reference, *reproject(*outline(dem), dem.srs, raster_srs(ds)),
                                   reference_nodata, feedback)
    except InputError:
        raise no_overlap from None
    finer = np.prod(cell_metres(ds.GetGeoTransform(), raster_srs(ds), ds.RasterYSize)) < np.prod(dem.cell_metres())
    ref = warp_to(memory_dataset(window), dem, "average" if finer else "bilinear")
    if not np.isfinite(ref).any():
        raise no_overlap
    progress.step(feedback, 50, f"reference resampled onto the DEM grid ({'average' if finer else 'bilinear'})")
    valid = defined & np.isfinite(ref)
    x, y = (v[valid] for v in dem.centres())
    h = _ellipsoidal(dem.values[valid], x, y, dem.srs, dem_datum)
    href = _ellipsoidal(ref[valid], x, y, dem.srs, reference_datum)
    dh = np.full(dem.shape, np.nan)
    dh[valid] = h - href
    slope = slope_degrees(Grid(ref, dem.geotransform, dem.srs))[valid]
    return Differences("DEM cells", str(path), dh[valid], x, y, dem.srs, slope,
                       grid=Grid(dh, dem.geotransform, dem.srs), valid=valid,
                       excluded={"DEM nodata": int((~defined).sum()),
                                 "outside the reference or on its nodata": int((defined & ~valid).sum())})


def write_dh_raster(path, grid):
    """The dh Grid as a float raster (surface.geotiff.write_float_raster: tiled, overviews, nodata, atomic)."""
    return str(write_float_raster(path, grid.values, grid.geotransform, grid.srs,
                                  "dh = DEM - reference (m, ellipsoidal)"))
