"""The accuracy assessment step (pushbroom:assessaccuracy): height differences of a point cloud and/or
a DEM against a reference DTM/DSM (assessment.assess_by_parts: in chunks and windows, memory following
them; Kornus et al. 2006 sections 3.6-3.7, Zhang and Gruen 2004 section 4), written as an HTML report with
figures, optionally a CSV table of the statistics and, for a DEM, a dh raster (its windows written as
tiles in a work folder beside it, assembled by GDAL)."""

import contextlib
from dataclasses import dataclass, field
from typing import Optional

from .. import progress
from ..adjustment.control_points import HEIGHT_TYPES
from ..atomic import atomic_path, work_dir
from ..errors import InputError
from ..progress import Feedback
from ..surface.geotiff import Frame, assemble_tiles
from .assessment import SLOPE_THRESHOLD, Labelling, assess_by_parts
from .classes import ClassRaster, PolygonClasses
from .height_differences import Reference


@dataclass
class AssessParams:
    """The assessment's settings; each is a pushbroom:assessaccuracy parameter. Datums are one of
    control_points.HEIGHT_TYPES."""

    reference: str = ""  # reference DTM/DSM raster
    report: str = ""  # HTML report path
    points: Optional[str] = None  # point cloud (LAS/LAZ, GeoPackage)
    dem: Optional[str] = None  # DEM raster
    reference_heights: str = "ellipsoidal"
    points_heights: str = "ellipsoidal"
    dem_heights: str = "ellipsoidal"
    class_raster: Optional[str] = None  # class raster, or
    class_polygons: Optional[PolygonClasses] = None  # class polygons,
    class_polygons_source: str = ""  # and their description in the report
    slope_threshold: float = SLOPE_THRESHOLD  # degrees: mountainous terrain above
    reference_nodata: Optional[float] = None  # void value of the reference its file does not flag
    table: Optional[str] = None  # CSV statistics table path
    dh: Optional[str] = None  # dh raster path (DEM input)

    def check(self):
        """Raise InputError for settings the assessment cannot use."""
        for datum in (self.reference_heights, self.points_heights, self.dem_heights):
            if datum not in HEIGHT_TYPES:
                raise InputError(f"heights must be one of {', '.join(HEIGHT_TYPES)}, not {datum!r}")
        if self.class_raster and self.class_polygons is not None:
            raise InputError("give a class raster or class polygons, not both")
        if self.dh and not self.dem:
            raise InputError("the dh raster needs a DEM input: give a DEM or leave the dh raster unset")
        return self


@dataclass
class AssessResult:
    """The files assess_accuracy wrote (None: not asked)."""

    report: str
    table: Optional[str] = None
    dh: Optional[str] = None
    used: list = field(default_factory=list)  # (what, description) of the inputs, as in the report


def assess_accuracy(params: AssessParams, feedback: Feedback | None = None) -> AssessResult:
    """Assess with AssessParams `params` and write the outputs; returns an AssessResult. Raises
    InputError (settings, inputs the reference does not cover) and the readers' errors."""
    params.check()
    classes: ClassRaster | PolygonClasses | None = None
    class_source = "none"
    if params.class_raster:
        classes, class_source = ClassRaster(params.class_raster), params.class_raster
    elif params.class_polygons is not None:
        classes, class_source = params.class_polygons, params.class_polygons_source
    with work_dir(params.dh, "the dh tiles") if params.dh else contextlib.nullcontext() as tiles:
        assessed = assess_by_parts(
            Reference(params.reference, params.reference_heights, params.reference_nodata),
            points=params.points,
            dem=params.dem,
            points_datum=params.points_heights,
            dem_datum=params.dem_heights,
            labelling=Labelling(classes, params.slope_threshold),
            feedback=progress.scaled(feedback, 0, 70),
            tiles=tiles,
        )
        return _write(params, assessed, class_source, feedback)


def _write(params, assessed, class_source, feedback):
    """The report, the table and the dh raster of the Summaries `assessed`."""
    used = [("reference", f"{params.reference} ({params.reference_heights} heights)")]
    if params.points:
        used.append(("point cloud", f"{params.points} ({params.points_heights} heights)"))
    if params.dem:
        used.append(("DEM", f"{params.dem} ({params.dem_heights} heights; reference resampled onto its grid)"))
    used += [("classes", class_source), ("slope threshold", f"{params.slope_threshold:g} deg")]
    from . import report  # matplotlib: loaded on use, not with the plugin

    progress.ensure(feedback).pushInfo(report.text(assessed, used))
    progress.step(feedback, 75, "drawing the figures")
    out = AssessResult(report.write_report(params.report, "Accuracy assessment", assessed, used), used=used)
    progress.step(feedback, 95)
    if params.table:
        out.table = report.write_csv(params.table, assessed)
    if params.dh:
        dem = next(a for a in assessed if a.tiles is not None)
        with atomic_path(params.dh) as tmp:
            assemble_tiles(
                dem.tiles,
                tmp,
                Frame(dem.geotransform, dem.size, dem.srs),
                description="dh = DEM - reference (m, ellipsoidal)",
                feedback=progress.scaled(feedback, 95, 100),
            )
        out.dh = str(params.dh)
    return out
