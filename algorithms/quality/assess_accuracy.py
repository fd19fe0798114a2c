"""The accuracy assessment step (pushbroom:assessaccuracy): height differences of a point cloud and/or
a DEM against a reference DTM/DSM (assessment.assess_by_parts: in chunks and windows, memory following
them; Kornus et al. 2006 sections 3.6-3.7, Zhang and Gruen 2004 section 4), written as an HTML report with
figures, optionally a CSV table of the statistics and, for a DEM, a dh raster (its windows written as
tiles in a work folder beside it, assembled by GDAL).

With `coregister` (and a DEM), the DEM is also co-registered to the reference over stable terrain
(coregistration.coregister, Nuth and Kääb 2011: the shift, and the tilt with `coregister_tilt`) and assessed
again as co-registered (coregister_dem.write_coregistered, in the work folder): the report gives the shift and
the statistics before and after side by side, so that it says what the shift was and what remains. Where
the terrain does not show the horizontal shift (coregistration.ShiftNotShownError), the vertical offset (and the tilt)
alone is co-registered, with a warning; a co-registration that fails otherwise (too few stable cells, no
convergence) is a warning, and the report stays that of the DEM as it lies."""

import contextlib
import os
from dataclasses import dataclass, field
from typing import Optional

from .. import progress
from ..adjustment.control_points import HEIGHT_TYPES
from ..atomic import work_dir
from ..errors import InputError
from ..execution import Execution
from ..progress import Feedback
from ..surface.geotiff import Frame, assemble_tiles, raster_output
from .assessment import SLOPE_THRESHOLD, Labelling, Summary, assess_by_parts
from .classes import ClassRaster, PolygonClasses
from .coregister_dem import write_coregistered
from .coregistration import CoregistrationError, CoregParams, CoregResult, coregister_or_vertical
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
    coregister: bool = True  # assess the DEM co-registered to the reference too
    coregister_tilt: bool = False  # and co-register with a tilt
    coregister_mask: Optional[str] = None  # unstable terrain left out of the co-registration (non-zero cells)
    execution: Execution = field(default_factory=Execution)  # where the co-registration's windows run
    cog: bool = False  # the dh raster as a Cloud-Optimised GeoTIFF

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
    coregistration: Optional[CoregResult] = None  # the DEM's co-registration, where asked and found


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
    reference = Reference(params.reference, params.reference_heights, params.reference_nodata)
    labelling = Labelling(classes, params.slope_threshold)
    end = 40 if params.coregister and params.dem else 70
    with work_dir(params.dh, "the dh tiles") if params.dh else contextlib.nullcontext() as tiles:
        assessed = assess_by_parts(
            reference,
            points=params.points,
            dem=params.dem,
            points_datum=params.points_heights,
            dem_datum=params.dem_heights,
            labelling=labelling,
            feedback=progress.scaled(feedback, 0, end),
            tiles=tiles,
        )
        if end == 70:
            return _write(params, reference, assessed, class_source, feedback)
        with work_dir(params.report, "the co-registered DEM") as folder:
            after = _coregistered(params, reference, labelling, folder, progress.scaled(feedback, 40, 70))
            return _write(params, reference, assessed, class_source, feedback, after)


def _coregistered(
    params: AssessParams, reference: Reference, labelling: Labelling, folder: str, feedback: Feedback | None
) -> tuple[CoregResult, Summary] | None:
    """(the co-registration of the DEM, the Summary of the co-registered DEM), or None with a warning where the
    co-registration fails (module docstring)."""
    coreg = CoregParams(
        dem_heights=params.dem_heights,
        reference_heights=params.reference_heights,
        reference_nodata=params.reference_nodata,
        tilt=params.coregister_tilt,
        mask=params.coregister_mask,
        execution=params.execution,
    )
    try:
        result = coregister_or_vertical(params.dem, reference, coreg, progress.scaled(feedback, 0, 50))
    except (CoregistrationError, InputError) as exc:
        progress.warn(feedback, f"no co-registration: {exc}. The report gives the DEM as it lies only")
        return None
    path = os.path.join(folder, "coregistered.tif")
    write_coregistered(params.dem, result.shift, result.units, path, coreg.execution, progress.scaled(feedback, 50, 60))
    (summary,) = assess_by_parts(
        reference,
        dem=path,
        dem_datum=params.dem_heights,
        labelling=labelling,
        feedback=progress.scaled(feedback, 60, 100),
    )
    summary.what, summary.source = "DEM cells after co-registration", str(params.dem)
    return result, summary


def _write(params, reference, assessed, class_source, feedback, coregistered=None):
    """The report, the table and the dh raster of the Summaries `assessed` (assess_by_parts': the DEM's last, where
    there is one) against `reference`, and of the co-registered DEM, where `coregistered` gives its co-registration
    and Summary."""
    dem = assessed[-1] if params.dem else None
    used = [("reference", f"{params.reference} ({params.reference_heights} heights)")]
    if params.points:
        used.append(("point cloud", f"{params.points} ({params.points_heights} heights)"))
    if params.dem:
        used.append(("DEM", f"{params.dem} ({params.dem_heights} heights; reference resampled onto its grid)"))
    used += [("classes", class_source), ("slope threshold", f"{params.slope_threshold:g} deg")]
    from . import report  # matplotlib: loaded on use, not with the plugin

    if coregistered is not None:
        result, after = coregistered
        used.append(
            ("co-registration", f"Nuth and Kääb 2011, {'shift and tilt' if params.coregister_tilt else 'shift'}")
        )
        comparison = report.Comparison(result, dem, after, reference)
        assessed = [*assessed, after]
    else:
        comparison = None
    progress.ensure(feedback).pushInfo(report.text(assessed, used, comparison))
    progress.step(feedback, 75, "drawing the figures")
    out = AssessResult(
        report.write_report(params.report, "Accuracy assessment", assessed, used, comparison),
        used=used,
        coregistration=comparison.result if comparison else None,
    )
    progress.step(feedback, 95)
    if params.table:
        out.table = report.write_csv(params.table, assessed)
    if params.dh:
        with raster_output(params.dh, params.cog, feedback if params.cog else None) as tmp:
            assemble_tiles(
                dem.tiles,
                tmp,
                Frame(dem.geotransform, dem.size, dem.srs),
                description="dh = DEM - reference (m, ellipsoidal)",
                feedback=progress.scaled(feedback, 95, 100),
            )
        out.dh = str(params.dh)
    return out
