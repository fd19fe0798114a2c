"""pushbroom:bundleadjust — bundle adjustment of the block from its control/check points and tie
points (algorithms/adjustment/bundle.py); the adjusted models are stored in the block."""
from qgis.core import (QgsProcessingOutputNumber, QgsProcessingParameterBoolean, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterString)

from ...algorithms import block
from ...algorithms.adjustment import report
from ...algorithms.adjustment.bundle import CRITICAL_W, adjust, check_points, statistics_table
from ...algorithms.adjustment.control_points import load_control_points
from ...algorithms.adjustment.observations import IMAGE_SIGMA, tie_observations
from ...algorithms.errors import InputError
from ...algorithms.matching import points
from .base import PushbroomAlgorithm
from .match_points import display_height, height_range_of

Number = QgsProcessingParameterNumber


class BundleAdjust(PushbroomAlgorithm):
    NAME = "bundleadjust"
    DISPLAY_NAME = "Bundle adjustment"
    GROUP = "Adjustment"
    GROUP_ID = "adjustment"
    HELP = ("Adjusts the block's orientation from its control points (ground and image coordinates) and tie "
            "points (image coordinates), Kornus et al. 2006 section 3.4. SPOT images: correction polynomials "
            "in time on position and attitude, common to a trajectory (one pass), and in the detector "
            "coordinate on each image's look angles; RPC images: an image-space bias (shift, drift or "
            "affine) per image. FREE lists the free parameters: patterns look:<degree>, exterior:<degree>, "
            "bias:shift|drift|affine, <kind>_<degrees> (e.g. psi_x_01, pitch_0) or full names. Check points "
            "take no part: they are intersected with the adjusted models and compared with their ground "
            "coordinates. Parameters the points cannot determine are named before solving. Data snooping "
            "flags measurements with normalised residuals above the critical value and, if asked, removes "
            "them one by one. The adjusted models replace the block's models.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterString("FREE", "Free parameters (comma-separated patterns)",
                                                       "look:0"))
        self.addParameter(QgsProcessingParameterBoolean("USE_TIE_POINTS", "Use the block's tie points", True))
        self.addParameter(QgsProcessingParameterBoolean("REMOVE_BLUNDERS", "Remove flagged measurements "
                                                        "iteratively", False))
        self.addAdvancedParameters([
            Number("SIGMA_TIE", "Sigma of tie point image measurements (px)", Number.Double, IMAGE_SIGMA, minValue=1e-4),
            Number("CRITICAL", "Critical normalised residual (data snooping)", Number.Double, CRITICAL_W,
                   minValue=1.0),
            Number("MAX_ITERATIONS", "Maximum iterations", Number.Integer, 15, minValue=1),
        ])
        self.addParameter(QgsProcessingParameterFileDestination("REPORT", "Report", "HTML files (*.html)",
                                                                optional=True))
        self.addOutput(QgsProcessingOutputNumber("SIGMA0", "sigma_0"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        rows = block.read_images(path)
        models = {r["id"]: block.load_model(path, r["id"]) for r in rows}
        names = {r["id"]: r["name"] for r in rows}
        obs = load_control_points(path)
        if not len(obs.points):
            raise InputError("the block has no control points: import them first (pushbroom:importpoints)")
        if self.parameterAsBool(parameters, "USE_TIE_POINTS", context):
            tie = tie_observations(points.load_points(path, "tie_points"),
                                   self.parameterAsDouble(parameters, "SIGMA_TIE", context))
            obs = obs.concatenate(tie)
        free = [f for f in self.parameterAsString(parameters, "FREE", context).split(",") if f.strip()]
        height = display_height(height_range_of(path, None, None))
        critical = self.parameterAsDouble(parameters, "CRITICAL", context)
        result = adjust(models, obs, free, names=names, height=height,
                        max_iterations=self.parameterAsInt(parameters, "MAX_ITERATIONS", context),
                        remove_blunders=self.parameterAsBool(parameters, "REMOVE_BLUNDERS", context),
                        critical=critical, feedback=feedback)
        check = check_points(result, obs, height)
        table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")}) if len(check["dE"]) else None
        text = report.text_report(result, check, table, critical)
        feedback.pushInfo(text)
        block.save_models(path, models, step="bundleadjust",
                          message=f"sigma_0 {result.sigma0:.4f}, free: {', '.join(free)}")
        out = {"BLOCK": path, "SIGMA0": result.sigma0}
        destination = self.parameterAsFileOutput(parameters, "REPORT", context)
        if destination:
            out["REPORT"] = report.write_html(destination, f"Bundle adjustment of {path}", text)
        return out
