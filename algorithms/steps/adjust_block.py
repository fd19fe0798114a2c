"""The bundle adjustment step (pushbroom:bundleadjust): adjust a block's orientation from its control
and tie points and store the result.

`adjust_block(block_path, params, feedback)`:

1. loads the supplied models (every adjustment starts from the orientation the block was created
   with), the control/check points and, with `use_tie_points`, the tie points (sigma `sigma_tie`);
   screens the control points for gross errors (screening.py): a control point whose ground
   coordinates are grossly off is an InputError naming it, or with `remove_blunders` it is left out
   (a warning); single measurements grossly off are noted and left to data snooping (a report section
   lists both);
2. adjusts with one of three solvers: the automatic parameter selection (selection.py, Kornus et al.
   2006 section 3.4.3) when `free` is "auto", else variance components (variance.py) or one plain
   adjustment (bundle.adjust) of the named free parameters. With the Lagrange model (orientation images,
   Heipke et al. 1992 section 3) "auto" means LAGRANGE_AUTO, adjusted as named parameters;
3. optionally runs the control point series (control_series.py, Heipke et al. 1992 Table 1);
4. intersects the check points with the adjusted models, compares the adjusted tie point heights
   with a reference DTM (tie_heights.py; Kornus et al. 2006 Table 4) and builds the residual vectors;
5. stores the adjusted models and the residuals in one block transaction, refused when the block's
   control points, tie points or models changed since step 1 (Block.generations);
6. writes the HTML report and the residual vector file when asked.

A solution that did not converge within `max_iterations` is not stored: the report (when asked) is
written with an alert section saying so, then a GeometryError says it, with the last point update.

A block without control points can only be adjusted with named free parameters and priors that fix
the datum (InputError otherwise)."""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from .. import progress
from ..adjustment import report
from ..adjustment.bundle import CRITICAL_W, AdjustmentSettings, adjust, check_points
from ..adjustment.control_points import HEIGHT_TYPES
from ..adjustment.control_series import control_point_series
from ..adjustment.observations import tie_observations
from ..adjustment.parameters import MODELS
from ..adjustment.residual_rows import residual_rows
from ..adjustment.residual_vectors import DEFAULT_SCALE, residual_vectors, write_residual_vectors
from ..adjustment.screening import describe, screen_control_points, without
from ..adjustment.selection import SelectionSettings, select_parameters
from ..adjustment.tie_heights import tie_height_differences
from ..adjustment.variance import adjust_with_components
from ..atomic import work_dir
from ..block import Block
from ..dem_store import store_dem
from ..errors import GeometryError, InputError
from ..height_range import mean_height
from ..sigmas import IMAGE_SIGMA
from ..stats import statistics_table

if TYPE_CHECKING:
    from ..adjustment.bundle import Adjustment
    from ..adjustment.observations import Observations
    from ..progress import Feedback
    from ..sensors.base import SensorModel

#: the free parameters "auto" stands for with the Lagrange model: attitude and offsets (the header
#: positions enter as priors)
LAGRANGE_AUTO = ["lagrange:attitude", "lagrange:offset"]


def parse_priors(text: str | None) -> dict[str, float]:
    """{pattern: sigma} of the text "pattern=sigma, ..." (commas or semicolons; empty text: none)."""
    priors: dict[str, float] = {}
    for item in (text or "").replace(";", ",").split(","):
        if not item.strip():
            continue
        pattern, _, value = item.partition("=")
        try:
            priors[pattern.strip()] = float(value)
        except ValueError:
            raise InputError(f"a prior is pattern=sigma (e.g. bias:shift=10), not {item.strip()!r}") from None
    return priors


def parse_counts(text: str | None) -> list[int]:
    """The control point counts of the text "4,6,10" (commas or semicolons; empty text: none)."""
    try:
        return [int(c) for c in (text or "").replace(";", ",").split(",") if c.strip()]
    except ValueError:
        raise InputError(f"control point counts must be whole numbers separated by commas, not {text!r}") from None


@dataclass
class AdjustParams:
    """The bundle adjustment's settings; each is a pushbroom:bundleadjust parameter."""

    free: str = "auto"  # "auto" or comma-separated parameter names/patterns
    model: str = "polynomial"  # one of parameters.MODELS
    use_tie_points: bool = True
    remove_blunders: bool = False  # remove flagged measurements one by one
    reference_dem: str | None = None  # DTM for the tie point height table
    reference_dem_nodata: float | None = None
    reference_heights: str = "ellipsoidal"  # one of control_points.HEIGHT_TYPES
    sigma_tie: float = IMAGE_SIGMA  # px, tie point measurements
    critical: float = CRITICAL_W  # critical normalised residual (data snooping)
    max_iterations: int = 15
    variance_components: bool = True
    significance: float = 3.0  # automatic selection: x/sigma threshold
    control_series: str = ""  # control point counts, e.g. "4,6,10"
    orientation_images: int = 4  # Lagrange model: orientation images per trajectory
    vector_scale: float = DEFAULT_SCALE
    priors: str = ""  # "pattern=sigma, ..."
    report: str | None = None  # HTML report path
    residual_vectors: str | None = None  # residual vector file (GeoPackage, shapefile, GeoJSON)

    @property
    def free_list(self) -> list[str]:
        """The FREE text as a list of names/patterns."""
        return [f for f in (self.free or "").split(",") if f.strip()]

    @property
    def auto(self) -> bool:
        return [f.strip().lower() for f in self.free_list] == ["auto"]

    def check(self) -> AdjustParams:
        """Raise InputError for settings the adjustment cannot use."""
        if self.model not in MODELS:
            raise InputError(f"the orientation model must be one of {', '.join(MODELS)}, not {self.model!r}")
        if self.reference_heights not in HEIGHT_TYPES:
            raise InputError(
                f"the reference DTM heights must be one of {', '.join(HEIGHT_TYPES)}, not {self.reference_heights!r}"
            )
        if self.residual_vectors and self.residual_vectors.startswith("memory:"):
            raise InputError(
                "write the residual vectors to a file (GeoPackage, shapefile or GeoJSON), not to a "
                "temporary memory layer"
            )
        parse_priors(self.priors)
        parse_counts(self.control_series)
        return self


@dataclass
class AdjustResult:
    """What adjust_block stored and wrote."""

    sigma0: float
    report: str | None = None  # the HTML report written, if asked
    residual_vectors: str | None = None  # the residual vector file written, if asked


def _solve(
    models: dict[int, SensorModel],
    obs: Observations,
    names: dict[int, str],
    params: AdjustParams,
    height: float,
    options: AdjustmentSettings,
    feedback: Feedback | None,
) -> tuple[Adjustment, Observations, list[str], list[report.Section]]:
    """(result, observations, free, extra report sections) of the solver the settings choose (the Lagrange
    model set in `options`, which the control point series then uses too)."""
    free, auto = params.free_list, params.auto
    extra: list[report.Section] = []
    if params.model == "lagrange":
        options.model, options.orientation_images = params.model, params.orientation_images
        if auto:
            free, auto = LAGRANGE_AUTO, False
            progress.ensure(feedback).pushInfo(
                f"Lagrange model: free {', '.join(free)} (header positions as priors: 1 m relative, offsets 1000 m)"
            )
    if auto:
        selection = select_parameters(
            models,
            obs,
            names=names,
            height=height,
            selection=SelectionSettings(
                significance=params.significance, variance_components=params.variance_components
            ),
            adjustment=options,
            feedback=feedback,
        )
        extra.append(report.Section("Parameter selection (Kornus et al. 2006, section 3.4.3)", notes=selection.log))
        if selection.components:
            extra.append(report.variance_section(selection.components))
        return selection.result, selection.observations, selection.free, extra
    if params.variance_components:
        result, obs, components = adjust_with_components(
            models, obs, free, names=names, height=height, settings=options, feedback=feedback
        )
        return result, obs, free, [report.variance_section(components)]
    result = adjust(models, obs, free, names=names, height=height, settings=options, feedback=feedback)
    return result, obs, free, extra


def _screened(
    models: dict[int, SensorModel], obs: Observations, names: dict[int, str], remove: bool, feedback: Feedback | None
) -> tuple[Observations, list[report.Section]]:
    """(observations, report sections) after screening the control points for gross errors
    (screening.py): control points whose ground coordinates are grossly off are an InputError naming
    them, or with `remove` left out with a warning; measurements grossly off in some images only are
    noted and left to data snooping. A report section lists the suspects when the adjustment goes on."""
    screening = screen_control_points(models, obs)
    if not screening.suspects:
        return obs, []
    wrong = screening.ground_points()
    if wrong and not remove:
        raise InputError(
            f"control point(s) grossly off: {describe(screening, obs, names, wrong)}. Check their "
            "coordinates and measurements (the measurement window), make them check points "
            "(importpoints CHECK_IDS) to see their error after the adjustment, or set REMOVE_BLUNDERS "
            "to leave them out"
        )
    notes = []
    if wrong:
        notes.append(f"left out before the adjustment, grossly off: {describe(screening, obs, names, wrong)}")
        progress.warn(feedback, notes[-1])
    single = {s.point for s in screening.suspects} - wrong
    if single:
        notes.append(f"far off, left to data snooping: {describe(screening, obs, names, single)}")
        progress.ensure(feedback).pushInfo(notes[-1])
    points = obs.points["name"]
    section = report.Section(
        "Control point screening (gross errors)",
        ("point", "image", "offset px", "offset m", "|e| / s", "action"),
        [
            (
                str(points[c.point]),
                names.get(c.image_id, str(c.image_id)),
                f"{c.offset_px:.1f}",
                f"{c.offset_m:.0f}",
                f"{c.ratio:.1f}",
                "point left out" if c.point in wrong else "data snooping",
            )
            for c in screening.suspects
        ],
        notes
        + [
            "offset: from where the other control points put the point in that image, "
            "with the supplied orientation (screening.py)"
        ],
    )
    return without(obs, wrong), [section]


def adjust_block(block_path: str, params: AdjustParams, feedback: Feedback | None = None) -> AdjustResult:
    """Adjust the block at `block_path` with AdjustParams `params` (module docstring); returns an
    AdjustResult. Raises InputError (settings, no control points, control points grossly off), the
    solvers' errors, GeometryError when the solution did not converge (nothing stored), and
    Block.transaction's StorageError when the block changed meanwhile. A reference DTM that holds no
    adjusted tie point is a warning (the height table is empty)."""
    params.check()
    priors = parse_priors(params.priors)
    blk = Block(block_path)
    blk.check_writable("the adjusted models")
    generations = blk.generations()
    rows = blk.images()
    models = blk.models(supplied=True)
    names = {r["id"]: r["name"] for r in rows}
    obs = blk.control_points()
    if params.use_tie_points:
        obs = obs.concatenate(tie_observations(blk.points("tie_points"), params.sigma_tie))
    if not (obs.points["role"] == "control").any() and (params.auto or not priors):
        raise InputError(
            "the block has no control points: import them (pushbroom:importpoints), or adjust "
            "with tie points alone by naming the free parameters and priors that fix the "
            "datum (e.g. FREE bias:shift, PRIORS bias:shift=10 for RPC images)"
        )
    obs, screened = _screened(models, obs, names, params.remove_blunders, feedback)
    height = mean_height(blk.height_range())
    with contextlib.ExitStack() as stack:  # the reference DEM's work folder, where there is one
        dem = None
        if params.reference_dem:
            dem = store_dem(
                params.reference_dem,
                stack.enter_context(work_dir(block_path, "the stored reference DEM")),
                params.reference_dem_nodata,
            )
            progress.warn(feedback, dem.implausible)
        options = AdjustmentSettings(
            critical=params.critical,
            priors=priors,
            max_iterations=params.max_iterations,
            remove_blunders=params.remove_blunders,
        )
        result, obs, free, extra = _solve(models, obs, names, params, height, options, feedback)
        extra[:0] = screened
        counts = parse_counts(params.control_series)
        if counts:
            series = control_point_series(
                blk.models(supplied=True),  # _solve adjusted `models`
                obs,
                counts,
                free,
                names=names,
                height=height,
                settings=replace(options, remove_blunders=False),
                feedback=feedback,
            )
            extra.append(report.series_section(series))
        check = check_points(result, obs, height)
        table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")}) if len(check["dE"]) else None
        heights = None
        if dem is not None:
            datum = params.reference_heights
            heights = (
                tie_height_differences(result, dem, datum),
                f"{params.reference_dem}, {'EGM96 ' if datum == 'orthometric' else ''}{datum} heights",
            )
            if not len(heights[0].dh):
                progress.warn(
                    feedback,
                    "no adjusted tie point lies on the reference DTM: the tie point height table "
                    "is empty (use the block's tie points and a DTM that covers the block)",
                )
    vectors, crs = residual_vectors(
        result, check, obs, params.vector_scale, blk.info().get("default_crs"), params.critical
    )
    parts = report.sections(result, check, table, params.critical, heights, vectors)
    at = next(k for k, part in enumerate(parts) if not part.alert) + 1  # after the "Adjustment" section
    parts[at:at] = extra
    progress.ensure(feedback).pushInfo(report.render_text(parts))
    if not result.converged:
        written = (
            report.write_html(params.report, f"Bundle adjustment of {block_path} (not converged)", parts=parts)
            if params.report
            else None
        )
        raise GeometryError(
            f"the adjustment did not converge in {result.iterations} iteration(s) (the last point "
            f"update was {result.last_update:.3g} m): nothing was stored, the block keeps its models"
            + (f"; the report {written} shows the last iteration" if written else "")
            + ". Raise MAX_ITERATIONS; if it still does not converge, free fewer parameters "
            "(e.g. FREE look:0) or check the control points"
        )
    residuals = residual_rows(result, check, obs)
    # storage: the adjusted models and the residuals in one transaction, if the block is unchanged
    with blk.transaction("the adjusted models and residuals", expect=generations) as tx:
        tx.write_models(models, step="bundleadjust", message=f"sigma_0 {result.sigma0:.4f}, free: {', '.join(free)}")
        tx.write_residuals(*residuals)
    out = AdjustResult(result.sigma0)
    if params.report:
        out.report = report.write_html(params.report, f"Bundle adjustment of {block_path}", parts=parts)
    if params.residual_vectors:
        out.residual_vectors = write_residual_vectors(params.residual_vectors, vectors, crs, params.vector_scale)
    return out
