"""pushbroom:bundleadjust — bundle adjustment of the block from its control/check points and tie
points (algorithms/adjustment/bundle.py); the adjusted models and the control and check points'
residuals (algorithms/measurement/residuals.py) are stored in the block, with a
report (K Tables 2-4; adjustment/report.py) and a residual-vector layer of the control and check
points (adjustment/residual_vectors.py). The models and residuals are stored in one transaction, and only if
the block's control points, tie points and models are still those the adjustment started from
(Block.generations)."""
from qgis.core import (QgsProcessing, QgsProcessingOutputFile, QgsProcessingOutputNumber,
                       QgsProcessingParameterBoolean, QgsProcessingParameterEnum, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterRasterLayer, QgsProcessingParameterString,
                       QgsProcessingParameterVectorDestination)

from ...algorithms import progress
from ...algorithms.adjustment import report
from ...algorithms.adjustment.bundle import CRITICAL_W, adjust, check_points
from ...algorithms.adjustment.control_points import HEIGHT_TYPES
from ...algorithms.adjustment.control_series import control_point_series
from ...algorithms.adjustment.observations import IMAGE_SIGMA, tie_observations
from ...algorithms.adjustment.residual_vectors import DEFAULT_SCALE, residual_vectors, write_residual_vectors
from ...algorithms.adjustment.selection import select_parameters
from ...algorithms.adjustment.tie_heights import tie_height_differences
from ...algorithms.adjustment.variance import adjust_with_components
from ...algorithms.block import Block
from ...algorithms.dem import Dem
from ...algorithms.errors import InputError
from ...algorithms.stats import statistics_table
from ...algorithms.measurement.residuals import residual_rows
from ..styles import load_styled
from .base import PushbroomAlgorithm
from .dem_nodata import nodata_parameter
from .import_points import HEIGHTS
from ...algorithms.height_range import mean_height

Number = QgsProcessingParameterNumber
#: the MODEL choices: parameters.OrientationParameters model -> label
MODELS = {"polynomial": "Correction polynomials with autocalibration (Kornus et al. 2006)",
          "lagrange": "Lagrange polynomials on orientation images (Hofmann, 003 section 3)"}
#: FREE = auto with the Lagrange model: H's setting (header positions enter as priors)
LAGRANGE_AUTO = ["lagrange:attitude", "lagrange:offset"]


def parse_priors(text):
    """{pattern: sigma} of the PRIORS parameter "pattern=sigma, ..." (empty text: none)."""
    priors = {}
    for item in (text or "").replace(";", ",").split(","):
        if not item.strip():
            continue
        pattern, _, value = item.partition("=")
        try:
            priors[pattern.strip()] = float(value)
        except ValueError:
            raise InputError(f"a prior is pattern=sigma (e.g. bias:shift=10), not {item.strip()!r}") from None
    return priors


class BundleAdjust(PushbroomAlgorithm):
    NAME = "bundleadjust"
    DISPLAY_NAME = "Bundle adjustment"
    GROUP = "Adjustment"
    GROUP_ID = "adjustment"
    HELP = ("Adjusts the block's orientation from its control points (ground and image coordinates) and tie "
            "points (image coordinates), Kornus et al. 2006 section 3.4. SPOT images: correction polynomials "
            "in time on position and attitude, common to a trajectory (one pass), and in the detector "
            "coordinate on each image's look angles; RPC images: an image-space bias (shift, drift or "
            "affine) per image. FREE is 'auto' (the default) or the free parameters: patterns look:<degree>, "
            "exterior:<degree>, bias:shift|drift|affine, <kind>_<degrees> (e.g. psi_x_01, pitch_0) or full "
            "names. 'auto' selects them as in K 3.4.3: all look-angle (bias) coefficients free with the "
            "exterior ones fixed, the insignificant ones (x/sigma below the threshold) fixed one by one unless "
            "that makes the control residuals larger or systematic, then the attitude and position "
            "coefficients tested the same way with the chosen set free, every step logged. With variance "
            "components (default) the sigmas of the tie point measurements, the control/check point "
            "measurements and the control/check ground coordinates are estimated from the data. MODEL "
            "'Lagrange' (SPOT 1-4, Hofmann 003 section 3) takes the exterior orientation at 2-4 orientation "
            "images per trajectory as unknowns (any line's by the Lagrange polynomial through them), the header "
            "positions as observations (1 m relative, offset unknowns of 1000 m); 'auto' then frees the "
            "attitude and the offsets (patterns lagrange:attitude|position|offset|all, <kind>@<nodes>). PRIORS adds "
            "prior observations x = 0 +- sigma of orientation unknowns (pattern=sigma); with priors and named free "
            "parameters a block of tie points alone can be adjusted (e.g. RPC images: FREE bias:shift, PRIORS "
            "bias:shift=10: the images are shifted relative to each other within a few pixels). Check points "
            "take no part: they are intersected with the adjusted models and compared with their ground "
            "coordinates. Parameters the points cannot determine are named before solving. Data snooping "
            "flags measurements with normalised residuals above the critical value and, if asked, removes "
            "them one by one. The adjusted models replace the block's models. The report gives the "
            "coefficients (K Table 2), the check point differences dE, dN, dH (K Table 3) and, with a reference "
            "DTM, the adjusted tie point heights against it (K Table 4; a DTM in EGM96 heights such as SRTM is "
            "converted to ellipsoidal heights at the points), and the residuals per control and check point. "
            "The residual-vector layer (block's UTM zone) has one line per control and check point from its "
            "reference position to the position plus the planimetric residual (computed - reference) times "
            "the vector scale, with dE, dN, dH (m), their sigmas, the image residual RMS (px), the largest "
            "|normalised residual| and whether it exceeds the critical value (check points: residuals of their "
            "forward intersection with the adjusted models). Every adjustment starts from the orientation the block was "
            "created with, so adjusting again gives the first adjustment's result, not a correction of it.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterString("FREE", "Free parameters ('auto' or comma-separated "
                                                       "patterns)", "auto"))
        self.addParameter(QgsProcessingParameterEnum("MODEL", "Exterior orientation model of SPOT images",
                                                     list(MODELS.values()), defaultValue=0))
        self.addParameter(QgsProcessingParameterBoolean("USE_TIE_POINTS", "Use the block's tie points", True))
        self.addParameter(QgsProcessingParameterBoolean("REMOVE_BLUNDERS", "Remove flagged measurements "
                                                        "iteratively", False))
        self.addParameter(QgsProcessingParameterRasterLayer(
            "REFERENCE_DEM", "Reference DTM for the tie point heights (K Table 4)", optional=True))
        self.addParameter(QgsProcessingParameterEnum("REFERENCE_HEIGHTS", "Heights of the reference DTM",
                                                     list(HEIGHTS), defaultValue=0))
        self.addAdvancedParameters([
            Number("SIGMA_TIE", "Sigma of tie point image measurements (px)", Number.Double, IMAGE_SIGMA,
                   minValue=1e-4),
            Number("CRITICAL", "Critical normalised residual (data snooping)", Number.Double, CRITICAL_W,
                   minValue=1.0),
            Number("MAX_ITERATIONS", "Maximum iterations", Number.Integer, 15, minValue=1),
            QgsProcessingParameterBoolean("VARIANCE_COMPONENTS", "Estimate variance components (tie, control "
                                          "image, control ground)", True),
            Number("SIGNIFICANCE", "Automatic selection: significance threshold x/sigma", Number.Double, 3.0,
                   minValue=0.0),
            QgsProcessingParameterString("CONTROL_SERIES", "Check point accuracy vs number of control points "
                                         "(H Table 1): counts, e.g. 4,6,10", "", optional=True),
            Number("ORIENTATION_IMAGES", "Lagrange model: orientation images per trajectory", Number.Integer, 4,
                   minValue=2, maxValue=4),
            Number("VECTOR_SCALE", "Scale of the residual vectors on the map", Number.Double, DEFAULT_SCALE,
                   minValue=1e-3),
            QgsProcessingParameterString("PRIORS", "Prior sigmas of orientation unknowns: pattern=sigma, ... "
                                         "(m, rad, px; e.g. bias:shift=10)", "", optional=True),
            nodata_parameter("REFERENCE_DEM_NODATA", "reference DTM"),
        ])
        self.addParameter(QgsProcessingParameterFileDestination("REPORT", "Report", "HTML files (*.html)",
                                                                optional=True))
        self.addParameter(QgsProcessingParameterVectorDestination(
            "RESIDUALS", "Residual vectors of control and check points", QgsProcessing.TypeVectorLine,
            optional=True, createByDefault=False))
        self.addOutput(QgsProcessingOutputNumber("SIGMA0", "sigma_0"))
        self.addOutput(QgsProcessingOutputFile("BLOCK", "Block (updated; chains the next step in a model)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        blk.check_writable("the adjusted models")
        vector_path = self.parameterAsOutputLayer(parameters, "RESIDUALS", context)
        if vector_path and vector_path.startswith("memory:"):
            raise InputError("write the residual vectors to a file (GeoPackage, shapefile or GeoJSON), not to a "
                             "temporary memory layer")
        generations = blk.generations()
        rows = blk.images()
        models = {r["id"]: blk.model(r["id"], supplied=True) for r in rows}
        names = {r["id"]: r["name"] for r in rows}
        obs = blk.control_points()
        if self.parameterAsBool(parameters, "USE_TIE_POINTS", context):
            tie = tie_observations(blk.points("tie_points"),
                                   self.parameterAsDouble(parameters, "SIGMA_TIE", context))
            obs = obs.concatenate(tie)
        free = [f for f in self.parameterAsString(parameters, "FREE", context).split(",") if f.strip()]
        auto = [f.strip().lower() for f in free] == ["auto"]
        priors = parse_priors(self.parameterAsString(parameters, "PRIORS", context))
        if not (obs.points["role"] == "control").any() and (auto or not priors):
            raise InputError("the block has no control points: import them (pushbroom:importpoints), or adjust "
                             "with tie points alone by naming the free parameters and priors that fix the "
                             "datum (e.g. FREE bias:shift, PRIORS bias:shift=10 for RPC images)")
        height = mean_height(blk.height_range())
        critical = self.parameterAsDouble(parameters, "CRITICAL", context)
        dem_layer = self.parameterAsRasterLayer(parameters, "REFERENCE_DEM", context)
        dem = None
        if dem_layer is not None:
            dem = Dem.from_file(dem_layer.source(),
                                self.parameterAsOptionalDouble(parameters, "REFERENCE_DEM_NODATA", context))
            progress.warn(feedback, dem.implausible)
        options = {"height": height, "critical": critical, "priors": priors,
                   "max_iterations": self.parameterAsInt(parameters, "MAX_ITERATIONS", context),
                   "remove_blunders": self.parameterAsBool(parameters, "REMOVE_BLUNDERS", context)}
        variance = self.parameterAsBool(parameters, "VARIANCE_COMPONENTS", context)
        model = list(MODELS)[self.parameterAsEnum(parameters, "MODEL", context)]
        extra = []
        if model == "lagrange":
            options.update(model=model,
                           orientation_images=self.parameterAsInt(parameters, "ORIENTATION_IMAGES", context))
            if auto:
                free = LAGRANGE_AUTO
                feedback.pushInfo(f"Lagrange model: free {', '.join(free)} (header positions as priors: 1 m "
                                  "relative, offsets 1000 m)")
                auto = False
        if auto:
            selection = select_parameters(models, obs, names=names, variance_components=variance,
                                          significance=self.parameterAsDouble(parameters, "SIGNIFICANCE", context),
                                          feedback=feedback, **options)
            result, obs, free = selection.result, selection.observations, selection.free
            extra.append(report.Section("Parameter selection (K 3.4.3)", notes=selection.log))
            if selection.components:
                extra.append(report.variance_section(selection.components))
        elif variance:
            result, obs, components = adjust_with_components(models, obs, free, names=names, feedback=feedback,
                                                             **options)
            extra.append(report.variance_section(components))
        else:
            result = adjust(models, obs, free, names=names, feedback=feedback, **options)
        counts = self.parameterAsString(parameters, "CONTROL_SERIES", context)
        if counts and counts.strip():
            try:
                counts = [int(c) for c in counts.replace(";", ",").split(",") if c.strip()]
            except ValueError:
                raise InputError(f"control point counts must be whole numbers separated by commas, not {counts!r}")
            series = control_point_series({r["id"]: blk.model(r["id"], supplied=True) for r in rows},
                                          obs, counts,
                                          free, names=names, feedback=feedback,
                                          **{k: v for k, v in options.items() if k != "remove_blunders"})
            extra.append(report.series_section(series))
        check = check_points(result, obs, height)
        table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")}) if len(check["dE"]) else None
        heights = None
        if dem is not None:
            datum = HEIGHT_TYPES[self.parameterAsEnum(parameters, "REFERENCE_HEIGHTS", context)]
            heights = (tie_height_differences(result, dem, datum),
                       f"{dem_layer.source()}, {'EGM96 ' if datum == 'orthometric' else ''}{datum} heights")
            if not len(heights[0].dh):
                feedback.pushWarning("no adjusted tie point lies on the reference DTM: the tie point height table "
                                     "is empty (use the block's tie points and a DTM that covers the block)")
        scale = self.parameterAsDouble(parameters, "VECTOR_SCALE", context)
        vectors, crs = residual_vectors(result, check, obs, scale, blk.info().get("default_crs"),
                                        critical)
        parts = report.sections(result, check, table, critical, heights, vectors)
        parts[1:1] = extra
        feedback.pushInfo(report.render_text(parts))
        residuals = residual_rows(result, check, obs)
        with blk.transaction("the adjusted models and residuals", expect=generations) as tx:
            tx.write_models(models, step="bundleadjust",
                            message=f"sigma_0 {result.sigma0:.4f}, free: {', '.join(free)}")
            tx.write_residuals(*residuals)
        out = {"BLOCK": path, "SIGMA0": result.sigma0}
        destination = self.parameterAsFileOutput(parameters, "REPORT", context)
        if destination:
            out["REPORT"] = report.write_html(destination, f"Bundle adjustment of {path}", parts=parts)
        if vector_path:
            out["RESIDUALS"] = write_residual_vectors(vector_path, vectors, crs, scale)
            load_styled(context, vector_path, "Residual vectors", "RESIDUALS", "residual_vectors.qml")
        return out
