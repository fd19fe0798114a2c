"""pushbroom:bundleadjust — the Processing face of steps.adjust_block.adjust_block: reads the
parameters, adjusts the block, loads the residual vectors."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputFile,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorDestination,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.adjustment.parameters import MODELS
from ...algorithms.steps.adjust_block import AdjustParams, adjust_block
from ..styles import load_styled
from .base import PushbroomAlgorithm, heights_choice, heights_parameter, translate, translated
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber
#: labels of the MODEL choices (parameters.MODELS)
MODEL_LABELS = {
    "polynomial": QT_TRANSLATE_NOOP("Pushbroom", "Correction polynomials with autocalibration (Kornus et al. 2006)"),
    "lagrange": QT_TRANSLATE_NOOP("Pushbroom", "Lagrange polynomials on orientation images (Heipke et al. 1992)"),
}


class BundleAdjust(PushbroomAlgorithm):
    NAME = "bundleadjust"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Bundle adjustment")
    GROUP_ID = "adjustment"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    FREE = "FREE"
    MODEL = "MODEL"
    USE_TIE_POINTS = "USE_TIE_POINTS"
    REMOVE_BLUNDERS = "REMOVE_BLUNDERS"
    REFERENCE_DEM = "REFERENCE_DEM"
    REFERENCE_HEIGHTS = "REFERENCE_HEIGHTS"
    SIGMA_TIE = "SIGMA_TIE"
    CRITICAL = "CRITICAL"
    MAX_ITERATIONS = "MAX_ITERATIONS"
    VARIANCE_COMPONENTS = "VARIANCE_COMPONENTS"
    SIGNIFICANCE = "SIGNIFICANCE"
    CONTROL_SERIES = "CONTROL_SERIES"
    ORIENTATION_IMAGES = "ORIENTATION_IMAGES"
    VECTOR_SCALE = "VECTOR_SCALE"
    PRIORS = "PRIORS"
    REFERENCE_DEM_NODATA = "REFERENCE_DEM_NODATA"
    REPORT = "REPORT"
    RESIDUALS = "RESIDUALS"
    SIGMA0 = "SIGMA0"

    def initAlgorithm(self, config=None):
        d = AdjustParams()
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterString(
                self.FREE, translate("Pushbroom", "Free parameters ('auto' or comma-separated patterns)"), d.free
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.MODEL,
                translate("Pushbroom", "Exterior orientation model of SPOT images"),
                [translated(MODEL_LABELS[m]) for m in MODELS],
                defaultValue=MODELS.index(d.model),
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.USE_TIE_POINTS, translate("Pushbroom", "Use the block's tie points"), d.use_tie_points
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.REMOVE_BLUNDERS,
                translate("Pushbroom", "Remove flagged measurements iteratively"),
                d.remove_blunders,
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterLayer(
                self.REFERENCE_DEM,
                translate("Pushbroom", "Reference DTM for the tie point heights (Kornus et al. 2006, Table 4)"),
                optional=True,
            )
        )
        self.addParameter(
            heights_parameter(self.REFERENCE_HEIGHTS, translate("Pushbroom", "Heights of the reference DTM"))
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.SIGMA_TIE,
                    translate("Pushbroom", "Sigma of tie point image measurements (px)"),
                    Number.Double,
                    d.sigma_tie,
                    minValue=1e-4,
                ),
                Number(
                    self.CRITICAL,
                    translate("Pushbroom", "Critical normalised residual (data snooping)"),
                    Number.Double,
                    d.critical,
                    minValue=1.0,
                ),
                Number(
                    self.MAX_ITERATIONS,
                    translate("Pushbroom", "Maximum iterations"),
                    Number.Integer,
                    d.max_iterations,
                    minValue=1,
                ),
                QgsProcessingParameterBoolean(
                    self.VARIANCE_COMPONENTS,
                    translate("Pushbroom", "Estimate variance components (tie, control image, control ground)"),
                    d.variance_components,
                ),
                Number(
                    self.SIGNIFICANCE,
                    translate("Pushbroom", "Automatic selection: significance threshold x/sigma"),
                    Number.Double,
                    d.significance,
                    minValue=0.0,
                ),
                QgsProcessingParameterString(
                    self.CONTROL_SERIES,
                    translate(
                        "Pushbroom", "Control point counts of the accuracy table (Heipke et al. 1992), e.g. 4,6,10"
                    ),
                    d.control_series,
                    optional=True,
                ),
                Number(
                    self.ORIENTATION_IMAGES,
                    translate("Pushbroom", "Lagrange model: orientation images per trajectory"),
                    Number.Integer,
                    d.orientation_images,
                    minValue=2,
                    maxValue=4,
                ),
                Number(
                    self.VECTOR_SCALE,
                    translate("Pushbroom", "Scale of the residual vectors on the map"),
                    Number.Double,
                    d.vector_scale,
                    minValue=1e-3,
                ),
                QgsProcessingParameterString(
                    self.PRIORS,
                    translate(
                        "Pushbroom", "Prior sigmas of orientation unknowns (pattern=sigma, ...; e.g. bias:shift=10)"
                    ),
                    d.priors,
                    optional=True,
                ),
                nodata_parameter(self.REFERENCE_DEM_NODATA, translate("Pushbroom", "reference DTM")),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.REPORT,
                translate("Pushbroom", "Report"),
                translate("Pushbroom", "HTML files (*.html)"),
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterVectorDestination(
                self.RESIDUALS,
                translate("Pushbroom", "Residual vectors of control and check points"),
                QgsProcessing.TypeVectorLine,
                optional=True,
                createByDefault=False,
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.SIGMA0, translate("Pushbroom", "sigma_0")))
        self.addOutput(
            QgsProcessingOutputFile(
                self.BLOCK, translate("Pushbroom", "Block (updated; chains the next step in a model)")
            )
        )

    def adjust_params(self, parameters, context):
        """AdjustParams of the parameters."""
        dem = self.parameterAsRasterLayer(parameters, self.REFERENCE_DEM, context)
        return AdjustParams(
            model=MODELS[self.parameterAsEnum(parameters, self.MODEL, context)],
            reference_dem=dem.source() if dem is not None else None,
            reference_heights=heights_choice(self, parameters, self.REFERENCE_HEIGHTS, context),
            report=self.parameterAsFileOutput(parameters, self.REPORT, context) or None,
            residual_vectors=self.parameterAsOutputLayer(parameters, self.RESIDUALS, context) or None,
            **self.parameterValues(
                parameters,
                context,
                free=self.FREE,
                use_tie_points=self.USE_TIE_POINTS,
                remove_blunders=self.REMOVE_BLUNDERS,
                reference_dem_nodata=self.REFERENCE_DEM_NODATA,
                sigma_tie=self.SIGMA_TIE,
                critical=self.CRITICAL,
                max_iterations=self.MAX_ITERATIONS,
                variance_components=self.VARIANCE_COMPONENTS,
                significance=self.SIGNIFICANCE,
                control_series=self.CONTROL_SERIES,
                orientation_images=self.ORIENTATION_IMAGES,
                vector_scale=self.VECTOR_SCALE,
                priors=self.PRIORS,
            ),
        )

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = self.adjust_params(parameters, context)
        result = adjust_block(path, params, feedback)
        if result.residual_vectors:
            load_styled(context, params.residual_vectors, "Residual vectors", self.RESIDUALS, "residual_vectors.qml")
        return self.given(
            {
                self.BLOCK: path,
                self.SIGMA0: result.sigma0,
                self.REPORT: result.report,
                self.RESIDUALS: result.residual_vectors,
            }
        )
