"""pushbroom:coregisterdem — the Processing face of quality.coregister_dem.coregister_dem: the shift (and optional
tilt) of a DEM against a reference DEM over stable terrain (Nuth and Kääb 2011), the co-registered DEM and a
report."""

from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.quality.coregister_dem import CoregisterDemParams, coregister_dem
from ...algorithms.quality.coregistration import CoregParams
from ..styles import style_on_completion
from .base import (
    PushbroomAlgorithm,
    cog_parameter,
    execution_choice,
    execution_parameters,
    heights_choice,
    heights_parameter,
    translate,
)
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber


class CoregisterDem(PushbroomAlgorithm):
    NAME = "coregisterdem"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Co-register DEM to a reference (Nuth and Kääb)")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    DEM = "DEM"
    DEM_HEIGHTS = "DEM_HEIGHTS"
    REFERENCE = "REFERENCE"
    REFERENCE_HEIGHTS = "REFERENCE_HEIGHTS"
    MASK = "MASK"
    MAX_SLOPE = "MAX_SLOPE"
    TILT = "TILT"
    HORIZONTAL = "HORIZONTAL"
    OUTLIER_NMAD = "OUTLIER_NMAD"
    TOLERANCE = "TOLERANCE"
    MAX_ITERATIONS = "MAX_ITERATIONS"
    REFERENCE_NODATA = "REFERENCE_NODATA"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    COG = "COG"
    OUTPUT = "OUTPUT"
    REPORT = "REPORT"
    SHIFT_EAST = "SHIFT_EAST"
    SHIFT_NORTH = "SHIFT_NORTH"
    SHIFT_UP = "SHIFT_UP"
    NMAD_BEFORE = "NMAD_BEFORE"
    NMAD_AFTER = "NMAD_AFTER"

    def initAlgorithm(self, config=None):
        d = CoregParams()
        self.addParameter(QgsProcessingParameterRasterLayer(self.DEM, translate("Pushbroom", "DEM to co-register")))
        self.addParameter(heights_parameter(self.DEM_HEIGHTS, translate("Pushbroom", "DEM heights")))
        self.addParameter(
            QgsProcessingParameterRasterLayer(self.REFERENCE, translate("Pushbroom", "Reference DEM (DTM/DSM, lidar)"))
        )
        self.addParameter(heights_parameter(self.REFERENCE_HEIGHTS, translate("Pushbroom", "Reference heights")))
        self.addParameter(
            QgsProcessingParameterRasterLayer(
                self.MASK,
                translate("Pushbroom", "Unstable terrain mask (non-zero cells left out: forest, water, changes)"),
                optional=True,
            )
        )
        self.addParameter(
            Number(
                self.MAX_SLOPE,
                translate("Pushbroom", "Largest slope of stable terrain (degrees, of the reference)"),
                Number.Double,
                d.max_slope,
                minValue=0.1,
                maxValue=89.9,
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(self.TILT, translate("Pushbroom", "Fit a tilt (a plane) too"), d.tilt)
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.HORIZONTAL,
                translate("Pushbroom", "Fit the horizontal shift (off: the vertical offset and the tilt only)"),
                d.horizontal,
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.OUTLIER_NMAD,
                    translate("Pushbroom", "Outliers: |dh - median| beyond this many NMAD"),
                    Number.Double,
                    d.outlier_nmad,
                    minValue=0.5,
                ),
                Number(
                    self.TOLERANCE,
                    translate("Pushbroom", "Convergence: horizontal step below (cells)"),
                    Number.Double,
                    d.tolerance,
                    minValue=1e-5,
                ),
                Number(
                    self.MAX_ITERATIONS,
                    translate("Pushbroom", "Largest number of iterations"),
                    Number.Integer,
                    d.max_iterations,
                    minValue=1,
                ),
                nodata_parameter(self.REFERENCE_NODATA, translate("Pushbroom", "reference DEM")),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(
            QgsProcessingParameterRasterDestination(self.OUTPUT, translate("Pushbroom", "Co-registered DEM"))
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.REPORT,
                translate("Pushbroom", "Co-registration report"),
                translate("Pushbroom", "HTML files (*.html)"),
                optional=True,
                createByDefault=False,
            )
        )
        for key, label in (
            (self.SHIFT_EAST, translate("Pushbroom", "Shift east (m)")),
            (self.SHIFT_NORTH, translate("Pushbroom", "Shift north (m)")),
            (self.SHIFT_UP, translate("Pushbroom", "Vertical shift (m)")),
            (self.NMAD_BEFORE, translate("Pushbroom", "NMAD of dh on stable terrain before (m)")),
            (self.NMAD_AFTER, translate("Pushbroom", "NMAD of dh on stable terrain after (m)")),
        ):
            self.addOutput(QgsProcessingOutputNumber(key, label))

    def coregister_params(self, parameters, context):
        """CoregisterDemParams of the parameters."""
        mask = self.parameterAsRasterLayer(parameters, self.MASK, context)
        report = self.parameterAsFileOutput(parameters, self.REPORT, context)
        return CoregisterDemParams(
            dem=self.parameterAsRasterLayer(parameters, self.DEM, context).source(),
            reference=self.parameterAsRasterLayer(parameters, self.REFERENCE, context).source(),
            output=self.parameterAsOutputLayer(parameters, self.OUTPUT, context),
            report=report or None,
            cog=self.parameterAsBool(parameters, self.COG, context),
            coreg=CoregParams(
                dem_heights=heights_choice(self, parameters, self.DEM_HEIGHTS, context),
                reference_heights=heights_choice(self, parameters, self.REFERENCE_HEIGHTS, context),
                mask=mask.source() if mask is not None else None,
                execution=execution_choice(self, parameters, context),
                **self.parameterValues(
                    parameters,
                    context,
                    reference_nodata=self.REFERENCE_NODATA,
                    max_slope=self.MAX_SLOPE,
                    tilt=self.TILT,
                    horizontal=self.HORIZONTAL,
                    outlier_nmad=self.OUTLIER_NMAD,
                    tolerance=self.TOLERANCE,
                    max_iterations=self.MAX_ITERATIONS,
                ),
            ),
        )

    def execute(self, parameters, context, feedback):
        params = self.coregister_params(parameters, context)
        done = coregister_dem(params, feedback)
        style_on_completion(context, params.output, "dem.qml")
        shift = done.result.shift
        return self.given(
            {
                self.OUTPUT: done.output,
                self.REPORT: done.report,
                self.SHIFT_EAST: shift.east,
                self.SHIFT_NORTH: shift.north,
                self.SHIFT_UP: shift.up,
                self.NMAD_BEFORE: done.result.before.nmad,
                self.NMAD_AFTER: done.result.after.nmad,
            }
        )
