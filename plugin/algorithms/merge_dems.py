"""pushbroom:mergedems — the Processing face of products.merge_dems.merge_dems: several DEMs co-registered and merged
into one, weighted by their precision rasters, with the merged precision and count rasters."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.products.merge_dems import MergeOutputs, MergeParams, merge_dems
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

Number = QgsProcessingParameterNumber


class MergeDems(PushbroomAlgorithm):
    NAME = "mergedems"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Merge DEMs (co-registered, weighted by precision)")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    DEMS = "DEMS"
    PRECISIONS = "PRECISIONS"
    HEIGHTS = "HEIGHTS"
    COREGISTER = "COREGISTER"
    REFERENCE = "REFERENCE"
    REFERENCE_HEIGHTS = "REFERENCE_HEIGHTS"
    TILT = "TILT"
    CRS = "CRS"
    CELL = "CELL"
    OUTLIER_K = "OUTLIER_K"
    BLEND = "BLEND"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    COG = "COG"
    OUTPUT = "OUTPUT"
    PRECISION = "PRECISION"
    COUNT = "COUNT"
    CELLS = "CELLS"
    OUTLIERS = "OUTLIERS"

    def initAlgorithm(self, config=None):
        d = MergeParams(("", ""))
        self.addParameter(
            QgsProcessingParameterMultipleLayers(
                self.DEMS, translate("Pushbroom", "DEMs (the first one is the others' frame)"), QgsProcessing.TypeRaster
            )
        )
        self.addParameter(
            QgsProcessingParameterMultipleLayers(
                self.PRECISIONS,
                translate("Pushbroom", "Precision rasters (one per DEM, in the DEMs' order)"),
                QgsProcessing.TypeRaster,
                optional=True,
            )
        )
        self.addParameter(heights_parameter(self.HEIGHTS, translate("Pushbroom", "Heights of the DEMs")))
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.COREGISTER, translate("Pushbroom", "Co-register the DEMs first"), d.coregister
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterLayer(
                self.REFERENCE,
                translate("Pushbroom", "Reference to co-register to (empty: the first DEM)"),
                optional=True,
            )
        )
        self.addParameter(heights_parameter(self.REFERENCE_HEIGHTS, translate("Pushbroom", "Reference heights")))
        self.addParameter(
            QgsProcessingParameterBoolean(self.TILT, translate("Pushbroom", "Co-register with a tilt too"), d.tilt)
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, translate("Pushbroom", "Output CRS (empty: the first DEM's)"), None, optional=True
            )
        )
        self.addParameter(
            Number(
                self.CELL,
                translate("Pushbroom", "Cell size in CRS units (empty: the first DEM's)"),
                Number.Double,
                None,
                optional=True,
                minValue=0.0,
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.OUTLIER_K,
                    translate("Pushbroom", "Outliers: farther from the median than K (spread, precision)"),
                    Number.Double,
                    d.outlier_k,
                    minValue=0.5,
                ),
                Number(
                    self.BLEND,
                    translate("Pushbroom", "Cells over which a DEM's weight rises from its edge"),
                    Number.Integer,
                    d.blend,
                    minValue=0,
                    maxValue=1000,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, translate("Pushbroom", "Merged DEM")))
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.PRECISION,
                translate("Pushbroom", "Precision raster of the merged DEM"),
                optional=True,
                createByDefault=False,
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.COUNT, translate("Pushbroom", "Heights merged per cell"), optional=True, createByDefault=False
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.CELLS, translate("Pushbroom", "Cells with a height")))
        self.addOutput(QgsProcessingOutputNumber(self.OUTLIERS, translate("Pushbroom", "Outlying heights left out")))

    def merge_params(self, parameters, context):
        """MergeParams of the parameters."""

        def sources(key):
            return tuple(layer.source() for layer in self.parameterAsLayerList(parameters, key, context))

        reference = self.parameterAsRasterLayer(parameters, self.REFERENCE, context)
        return MergeParams(
            dems=sources(self.DEMS),
            precisions=sources(self.PRECISIONS),
            heights=heights_choice(self, parameters, self.HEIGHTS, context),
            reference=reference.source() if reference is not None else None,
            reference_heights=heights_choice(self, parameters, self.REFERENCE_HEIGHTS, context),
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            cell=self.parameterAsOptionalDouble(parameters, self.CELL, context),
            execution=execution_choice(self, parameters, context),
            cog=self.parameterAsBool(parameters, self.COG, context),
            **self.parameterValues(
                parameters,
                context,
                coregister=self.COREGISTER,
                tilt=self.TILT,
                outlier_k=self.OUTLIER_K,
                blend=self.BLEND,
            ),
        )

    def execute(self, parameters, context, feedback):
        params = self.merge_params(parameters, context)
        outputs = MergeOutputs(
            self.parameterAsOutputLayer(parameters, self.OUTPUT, context),
            self.parameterAsOutputLayer(parameters, self.PRECISION, context) or None,
            self.parameterAsOutputLayer(parameters, self.COUNT, context) or None,
        )
        result = merge_dems(params, outputs, feedback)
        style_on_completion(context, outputs.dem, "dem.qml")
        done = {self.OUTPUT: outputs.dem, self.PRECISION: outputs.precision, self.COUNT: outputs.count}
        return self.given({**done, self.CELLS: result.cells, self.OUTLIERS: result.outliers})
