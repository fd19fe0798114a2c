"""pushbroom:extractdtm — the Processing face of products.extract_dtm.extract_dtm: a DSM's DTM and height above the
ground with CNES Bulldozer, tile by tile."""

from qgis.core import (
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.products.extract_dtm import MIN_MARGIN, DtmOutputs, DtmParams, extract_dtm
from ..styles import style_on_completion
from .base import PushbroomAlgorithm, cog_parameter, execution_choice, execution_parameters, translate
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber


class ExtractDtm(PushbroomAlgorithm):
    NAME = "extractdtm"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Extract DTM and height above ground (Bulldozer)")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    DSM = "DSM"
    MAX_OBJECT_SIZE = "MAX_OBJECT_SIZE"
    MAX_GROUND_SLOPE = "MAX_GROUND_SLOPE"
    DSM_NODATA = "DSM_NODATA"
    TILE = "TILE"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    COG = "COG"
    OUTPUT = "OUTPUT"
    DHM = "DHM"
    MASK = "MASK"

    def initAlgorithm(self, config=None):
        d = DtmParams()
        self.addParameter(
            QgsProcessingParameterRasterLayer(self.DSM, translate("Pushbroom", "DSM (projected CRS, metres)"))
        )
        self.addParameter(
            Number(
                self.MAX_OBJECT_SIZE,
                translate("Pushbroom", "Largest object above the ground (m)"),
                Number.Double,
                d.max_object_size,
                minValue=0.1,
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.MAX_GROUND_SLOPE,
                    translate("Pushbroom", "Steepest ground slope (%)"),
                    Number.Double,
                    d.max_ground_slope,
                    minValue=0.1,
                ),
                nodata_parameter(self.DSM_NODATA, translate("Pushbroom", "DSM")),
                Number(
                    self.TILE,
                    translate("Pushbroom", "Tile side (cells)"),
                    Number.Integer,
                    d.tile,
                    minValue=3 * MIN_MARGIN,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, translate("Pushbroom", "DTM")))
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.DHM, translate("Pushbroom", "Height above ground (DSM - DTM)"), optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.MASK,
                translate("Pushbroom", "Bulldozer's mask (1 nodata filled, 2 pit filled)"),
                optional=True,
                createByDefault=False,
            )
        )

    def dtm_params(self, parameters, context):
        """DtmParams of the parameters."""
        return DtmParams(
            execution=execution_choice(self, parameters, context),
            cog=self.parameterAsBool(parameters, self.COG, context),
            **self.parameterValues(
                parameters,
                context,
                max_object_size=self.MAX_OBJECT_SIZE,
                max_ground_slope=self.MAX_GROUND_SLOPE,
                dsm_nodata=self.DSM_NODATA,
                tile=self.TILE,
            ),
        )

    def execute(self, parameters, context, feedback):
        outputs = DtmOutputs(
            self.parameterAsOutputLayer(parameters, self.OUTPUT, context),
            self.parameterAsOutputLayer(parameters, self.DHM, context) or None,
            self.parameterAsOutputLayer(parameters, self.MASK, context) or None,
        )
        dsm = self.parameterAsRasterLayer(parameters, self.DSM, context).source()
        written = extract_dtm(dsm, outputs, self.dtm_params(parameters, context), feedback)
        style_on_completion(context, outputs.dtm, "dem.qml")
        if outputs.dhm:
            style_on_completion(context, outputs.dhm, "dh.qml")
        keys = {"dtm": self.OUTPUT, "dhm": self.DHM, "mask": self.MASK}
        return {keys[k]: path for k, path in written.items()}
