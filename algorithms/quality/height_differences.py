"""Height differences dh = assessed height - reference height (m, both ellipsoidal WGS 84) of object
points and of DEM cells against a reference DTM/DSM raster in any CRS (Kornus et al. 2006, section 3.6-3.7,
Zhang and Gruen 2004, section 4.2-4.3).

Points: the reference is interpolated bilinearly between its cell centres at each point, in the
reference's own CRS (the points are transformed to it; dem.Dem.height on the window of cells
around the points), NaN next to nodata. DEM cells: the reference is resampled onto the DEM's grid
and CRS with gdalwarp: the average of the reference cells inside a DEM cell where the reference is
finer, bilinear otherwise. Vertical datum per input: "ellipsoidal" or "orthometric" (EGM96:
h = H + N, adjustment.control_points.orthometric_to_ellipsoidal at points; on a DEM's grid N from a lattice of at most
crs.UNDULATION_NODES a side, crs.undulation_rows). The slope (Kornus et al. 2006, section 3.7:
flat/moderate vs mountainous) is the reference's (rasters.slope_degrees): at the points, or on the DEM grid.

The reference is read by the window of its cells under the assessed data (for points, block by block of its
cells; for a DEM, under the DEM or under one window of it), its nodata and a declared void value
(`reference_nodata`) as NaN; implausible heights among those cells (outside height_range.PLAUSIBLE_HEIGHTS,
such as SRTM voids not flagged as nodata) are voids too, NaN like nodata: left out of the differences, never
a height error of kilometres in the statistics. They are counted once over the cells read (ReferenceReach)
and reported as a warning (progress.warn) naming their value and the REFERENCE_NODATA parameter. A point
cloud can be given in chunks and a DEM in windows (assessment.assess_by_parts), so that memory follows the
chunk and the window."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import progress
from ..adjustment.control_points import HEIGHT_TYPES, orthometric_to_ellipsoidal
from ..crs import reproject, undulation_rows, wgs84
from ..dem import Dem, ImplausibleTally
from ..errors import InputError
from ..height_range import outside_plausible
from ..progress import Feedback
from ..surface.point_input import PointSet, read_points
from .rasters import (
    Grid,
    by_blocks,
    mean_cell,
    memory_dataset,
    open_raster,
    outline,
    raster_srs,
    read_grid,
    read_window,
    resampling_for,
    slope_degrees,
    warp_to,
)


@dataclass(frozen=True)
class Reference:
    """The reference DTM/DSM raster: its `path`, the `datum` of its heights (control_points.HEIGHT_TYPES) and
    `nodata`, a void value its file does not flag as nodata (None: none)."""

    path: str | os.PathLike[str]
    datum: str = "ellipsoidal"
    nodata: float | None = None


@dataclass
class Differences:
    """dh of the assessed points or cells that have a reference height, with where they are."""

    what: str  # "object points" or "DEM cells"
    source: str  # the assessed file
    dh: np.ndarray  # (n,) m
    x: np.ndarray  # (n,) position in `srs` (the assessed data's CRS)
    y: np.ndarray
    srs: object
    slope: np.ndarray  # (n,) degrees, of the reference
    group: np.ndarray = None  # (n,) point group 1/2/3 where the point cloud has one
    grid: Grid = None  # DEM input: the dh grid (NaN where undefined)
    valid: np.ndarray = None  # DEM input: the grid cells in dh
    excluded: dict = field(default_factory=dict)  # {reason: count} of left-out points or cells


class ReferenceReach:
    """The cells of the reference that an assessment read, over all its windows (the box around them), and
    whether any held a height: the implausible heights are counted once over that box, band by band, and a
    reference without heights there is told from one that lies elsewhere."""

    #: rows of the reference read at a time to count its implausible heights
    ROWS = 512

    def __init__(self, reference, nodata=None):
        self.reference, self.nodata, self.box, self.heights = reference, nodata, None, False

    def add(self, ds, window):
        """Note the window (a rasters.Grid read from `ds`, the reference)."""
        x0, dx, _, y0, _, dy = ds.GetGeoTransform()
        c0, r0 = (int(round((window.geotransform[0] - x0) / dx)), int(round((window.geotransform[3] - y0) / dy)))
        box = (c0, r0, c0 + window.shape[1], r0 + window.shape[0])
        self.box = box if self.box is None else (*np.minimum(self.box[:2], box[:2]), *np.maximum(self.box[2:], box[2:]))
        self.heights = self.heights or bool(np.isfinite(window.values).any())

    def warning(self):
        """dem.implausible_warning of the reference's cells in the box, left out as voids (None: none read, or all
        plausible)."""
        if self.box is None:
            return None
        ds, tally = open_raster(self.reference, "reference DEM"), ImplausibleTally()
        c0, r0, c1, r1 = (int(v) for v in self.box)
        for row in range(r0, r1, self.ROWS):
            tally.add(read_grid(ds, self.nodata, (c0, row, c1, min(row + self.ROWS, r1))).values)
        return tally.warning(f"the reference DEM {self.reference}", left_out=REFERENCE_NODATA)

    def no_heights(self, what):
        """The InputError of a reference without a height under the assessed `what`."""
        if self.box is not None and not self.heights:
            return InputError(
                f"the reference DEM {self.reference} has only nodata where the assessed data are: "
                "choose a reference that covers them"
            )
        return InputError(
            f"the reference DEM {self.reference} does not overlap {what}: choose a reference that covers them"
        )


#: the assessment's parameter declaring the reference's void value, named in the warning of its implausible heights
REFERENCE_NODATA = "REFERENCE_NODATA"


def read_reference(ds, x, y, nodata=None):
    """rasters.read_window of the reference `ds` around points (x, y in its CRS), its implausible heights NaN as
    voids (module docstring)."""
    window = read_window(ds, x, y, "reference DEM", nodata=nodata)
    window.values[outside_plausible(window.values)] = np.nan
    return window


def _check_datum(datum, what):
    if datum not in HEIGHT_TYPES:
        raise InputError(f"the heights of the {what} must be one of {', '.join(HEIGHT_TYPES)}, not {datum!r}")


#: EPSG code of the EGM96 height vertical CRS, the orthometric heights the assessment converts
EGM96_HEIGHT = "5773"


def stated_heights(srs: Any) -> str | None:
    """The height type (control_points.HEIGHT_TYPES) a raster's CRS `srs` states: 'orthometric' for a compound CRS with
    EGM96 heights, 'ellipsoidal' for a 3-D geographic CRS (EPSG:4979), None where it states none (a 2-D CRS).
    InputError for any other vertical CRS (EGM2008, NAVD88, ...), which the assessment does not convert."""
    if srs is None:
        return None
    if srs.IsCompound() or srs.IsVertical():
        code = srs.GetAuthorityCode("VERT_CS")
        if code == EGM96_HEIGHT:
            return "orthometric"
        name = srs.GetAttrValue("VERT_CS") or "an unnamed vertical CRS"
        raise InputError(
            f"heights in {name} (EPSG:{code}) are neither ellipsoidal (WGS 84) nor EGM96 orthometric: convert the "
            "raster first (for example gdalwarp -t_srs EPSG:4979 for ellipsoidal heights) and run again"
        )
    if srs.IsGeographic() and srs.GetAxesCount() == 3:
        return "ellipsoidal"
    return None


def check_stated(ds: Any, datum: str, what: str, path: Any) -> None:
    """InputError where the CRS of the raster `ds` (the `what` at `path`) states heights of another type than the
    `datum` declared for it, so that heights of two datums are never mixed silently."""
    stated = stated_heights(ds.GetSpatialRef())
    if stated is not None and stated != datum:
        raise InputError(
            f"the {what} {path} states {stated} heights in its CRS, but its heights are declared {datum}: declare "
            f"them {stated}, or correct the raster's CRS"
        )


def ellipsoidal(h: np.ndarray, x: np.ndarray, y: np.ndarray, srs: Any, datum: str) -> np.ndarray:
    """Heights h at points (x, y in srs) made ellipsoidal (EGM96 -> + N) where finite."""
    h = np.array(h, float)
    ok = np.isfinite(h)
    if datum == "orthometric" and ok.any():
        lon, lat = reproject(x[ok], y[ok], srs, wgs84())
        h[ok] = orthometric_to_ellipsoidal(lon, lat, h[ok])
    return h


def reference_at_points(
    reference: Reference,
    x: np.ndarray,
    y: np.ndarray,
    srs: Any,
    feedback: Feedback | None = None,
    reach: ReferenceReach | None = None,
    required: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """(ellipsoidal reference height, reference slope in degrees) of the Reference `reference` at points
    (x, y in `srs`, an osr.SpatialReference): bilinear in the reference's CRS, the reference read by the
    window of each block of its cells that holds points (rasters.by_blocks); NaN outside it and next to its
    nodata (and cells equal to its declared void value). InputError when it does not overlap (unless not
    `required`: a chunk of a cloud). The cells read are noted in `reach` (ReferenceReach: a cloud's over all
    its chunks) where given, else their implausible heights are reported as a warning (`feedback`)."""
    path, datum, nodata = reference.path, reference.datum, reference.nodata
    _check_datum(datum, "reference")
    ds = open_raster(path, "reference DEM")
    check_stated(ds, datum, "reference DEM", path)
    xr, yr = reproject(x, y, srs, raster_srs(ds))
    counted = reach or ReferenceReach(path, nodata)
    href, slope = np.full(len(xr), np.nan), np.full(len(xr), np.nan)
    for index in by_blocks(ds, xr, yr):
        progress.check(feedback)
        try:
            window = read_reference(ds, xr[index], yr[index], nodata)
        except InputError:  # a block of points beyond the raster's last cells
            continue
        counted.add(ds, window)
        if np.isnan(window.values).all():
            continue
        href[index] = Dem(window.values, window.geotransform).height(xr[index], yr[index])
        slope[index] = Dem(slope_degrees(window), window.geotransform).height(xr[index], yr[index])
    if reach is None:
        progress.warn(feedback, counted.warning())
    if required and not np.isfinite(href).any():
        raise counted.no_heights("the assessed points")
    return ellipsoidal(href, x, y, srs, datum), slope


def point_differences(
    path: str | os.PathLike[str],
    reference: Reference,
    points_datum: str = "ellipsoidal",
    feedback: Feedback | None = None,
    points: PointSet | None = None,
    reach: ReferenceReach | None = None,
    required: bool = True,
) -> Differences:
    """Differences of the object points of a point cloud (surface.point_input.read_points; or `points`, a
    PointSet of it such as a chunk) against the Reference `reference` (the cells read noted in `reach` where
    given, and the overlap `required`, as reference_at_points); its `group` field, where present, is
    kept."""
    _check_datum(points_datum, "points")
    cloud = read_points(path) if points is None else points
    x, y, z, srs, fields = cloud.x, cloud.y, cloud.z, cloud.srs, cloud.fields
    if not len(x):
        raise InputError(f"the point cloud {path} holds no point")
    progress.step(feedback, 10, f"{len(x)} points read from {path}")
    href, slope = reference_at_points(reference, x, y, srs, feedback, reach, required)
    progress.step(feedback, 60)
    h = ellipsoidal(z, x, y, srs, points_datum)
    ok = np.isfinite(h) & np.isfinite(href)
    group = fields.get("group")
    return Differences(
        "object points",
        str(path),
        (h - href)[ok],
        x[ok],
        y[ok],
        srs,
        slope[ok],
        None if group is None else np.asarray(group)[ok].astype(np.int64),
        excluded={"outside the reference or next to its nodata": int((~ok).sum())},
    )


def dem_differences(
    path: str | os.PathLike[str],
    reference: Reference,
    dem_datum: str = "ellipsoidal",
    feedback: Feedback | None = None,
    window: tuple[int, int, int, int] | None = None,
    reach: ReferenceReach | None = None,
) -> Differences:
    """Differences of the cells of a DEM raster against the Reference `reference` resampled onto its grid:
    the reference's window under the DEM, warped. With `window` (c0, r0, c1, r1: cells of the DEM), those
    cells only, the reference's slope taken with one more cell around as on the whole grid; a window that
    the reference does not cover gives no differences instead of an InputError. The reference's cells read
    are noted in `reach` where given (ReferenceReach), else its implausible heights are a warning."""
    reference_datum, reference_nodata = reference.datum, reference.nodata
    _check_datum(dem_datum, "DEM")
    _check_datum(reference_datum, "reference")
    source = open_raster(path, "DEM")
    check_stated(source, dem_datum, "DEM", path)
    c0, r0, c1, r1 = window or (0, 0, source.RasterXSize, source.RasterYSize)
    g0, h0 = max(c0 - 1, 0), max(r0 - 1, 0)  # one cell around for the slope
    g1, h1 = min(c1 + 1, source.RasterXSize), min(r1 + 1, source.RasterYSize)
    wide = read_grid(source, window=(g0, h0, g1, h1))
    inner = (slice(r0 - h0, r0 - h0 + r1 - r0), slice(c0 - g0, c0 - g0 + c1 - c0))
    dem = Grid(wide.values[inner], _shifted(wide.geotransform, c0 - g0, r0 - h0), wide.srs)
    defined = np.isfinite(dem.values)
    if window is None and not defined.any():
        raise InputError(f"the DEM {path} holds no valid height (all cells are nodata)")
    progress.step(
        feedback, 10, f"DEM {path}: {dem.shape[1]} x {dem.shape[0]} cells, {int(defined.sum())} with a height"
    )
    ds = open_raster(reference.path, "reference DEM")
    check_stated(ds, reference_datum, "reference DEM", reference.path)
    no_overlap = InputError(
        f"the reference DEM {reference.path} does not overlap the DEM {path} (or holds only nodata "
        "there): choose a reference that covers it"
    )
    counted = reach or ReferenceReach(reference.path, reference_nodata)
    ref, method = np.full(wide.shape, np.nan), None
    if defined.any():
        method = resampling_onto(ds, source)
        ref = reference_on_grid(ds, wide, reference_nodata, counted, method)
    if reach is None:
        progress.warn(feedback, counted.warning())
    if window is None and not np.isfinite(ref).any():
        raise no_overlap
    progress.step(feedback, 50, f"reference resampled onto the DEM grid ({method})" if method else None)
    slope = slope_degrees(Grid(ref, wide.geotransform, wide.srs))[inner]
    ref = ref[inner]
    valid = defined & np.isfinite(ref)
    x, y = (v[valid] for v in dem.centres())
    h, href = dem.values[valid], ref[valid]
    if "orthometric" in (dem_datum, reference_datum) and valid.any():  # N on a lattice: crs.undulation_rows
        n = undulation_rows(dem.shape, dem.geotransform, dem.srs)(0, dem.shape[0])[valid]
        h, href = h + n * (dem_datum == "orthometric"), href + n * (reference_datum == "orthometric")
    dh = np.full(dem.shape, np.nan)
    dh[valid] = h - href
    return Differences(
        "DEM cells",
        str(path),
        dh[valid],
        x,
        y,
        dem.srs,
        slope[valid],
        grid=Grid(dh, dem.geotransform, dem.srs),
        valid=valid,
        excluded={
            "DEM nodata": int((~defined).sum()),
            "outside the reference or on its nodata": int((defined & ~valid).sum()),
        },
    )


def resampling_onto(reference: Any, dem: Any) -> str:
    """gdalwarp's resampling of the reference raster `reference` onto the cells of the DEM raster `dem` (GDAL
    datasets; rasters.resampling_for their mean cells)."""
    return resampling_for(reference, mean_cell(dem))


def reference_on_grid(ds: Any, grid: Grid, nodata: float | None, reach: ReferenceReach, method: str) -> np.ndarray:
    """The reference raster `ds` (its declared void value `nodata`) resampled onto the cells of `grid` (warp_to
    `method`) from the window of its cells under the grid, its implausible heights NaN as voids; all NaN where the
    reference lies elsewhere. The cells read are noted in `reach`."""
    try:
        ox, oy = outline(grid)
        xr, yr = reproject(ox, oy, grid.srs, raster_srs(ds))
        under = read_reference(ds, xr, yr, nodata)
    except InputError:  # the reference lies elsewhere
        return np.full(grid.shape, np.nan)
    reach.add(ds, under)
    return warp_to(memory_dataset(under), grid, method)


def _shifted(geotransform, cols, rows):
    """The geotransform of a grid starting `cols`, `rows` cells into the grid of `geotransform`."""
    x0, dx, _, y0, _, dy = geotransform
    return (x0 + cols * dx, dx, 0.0, y0 + rows * dy, 0.0, dy)
