"""pushbroom:createblock — the Processing face of block_creation.create_block: images and their
orientation into a block GeoPackage."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
    QgsProcessingUtils,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms import sensors
from ...algorithms.errors import PushbroomError
from ...algorithms.height_range import PLAUSIBLE_HEIGHTS
from ...algorithms.steps.block_creation import CreateParams, create_block
from ..styles import load_styled
from .base import PushbroomAlgorithm, execution_choice, execution_parameters, translate
from .dem_nodata import nodata_parameter


class CreateBlock(PushbroomAlgorithm):
    NAME = "createblock"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Create block")
    GROUP_ID = "block"

    # parameter and output keys: the names Processing, models and qgis_process use
    IMAGES = "IMAGES"
    ORIENTATION = "ORIENTATION"
    DEM = "DEM"
    HEIGHT = "HEIGHT"
    OVERWRITE = "OVERWRITE"
    DEM_NODATA = "DEM_NODATA"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    OUTPUT = "OUTPUT"
    FOOTPRINTS = "FOOTPRINTS"

    def initAlgorithm(self, config=None):
        d = CreateParams()
        self.addParameter(
            QgsProcessingParameterMultipleLayers(
                self.IMAGES, translate("Pushbroom", "Images"), QgsProcessing.TypeRaster
            )
        )
        self.addParameter(
            QgsProcessingParameterMultipleLayers(
                self.ORIENTATION,
                translate(
                    "Pushbroom", "Orientation files (one per image, same order; found beside the images if empty)"
                ),
                QgsProcessing.TypeFile,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterLayer(
                self.DEM, translate("Pushbroom", "DEM for the footprints (ellipsoidal heights)"), optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterNumber(
                self.HEIGHT,
                translate(
                    "Pushbroom", "Mean ellipsoidal height without a DEM (m, {:g} .. {:g}; empty: matched)"
                ).format(*PLAUSIBLE_HEIGHTS),
                QgsProcessingParameterNumber.Double,
                d.height,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.OVERWRITE, translate("Pushbroom", "Overwrite an existing block"), d.overwrite
            )
        )
        self.addAdvancedParameters(
            [nodata_parameter(self.DEM_NODATA), *execution_parameters(self, d.execution.workers)]
        )  # the height search
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT, translate("Pushbroom", "Block"), translate("Pushbroom", "GeoPackage (*.gpkg)")
            )
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.FOOTPRINTS, translate("Pushbroom", "Footprints"), QgsProcessing.TypeVectorPolygon
            )
        )

    def checkParameterValues(self, parameters, context):
        """QGIS's check; where it refuses the images, the engine's reason for a file path that is no
        layer (a missing file, a SPOT DIMAP product without its raster) instead of 'Incorrect parameter
        value for IMAGES'."""
        ok, message = super().checkParameterValues(parameters, context)
        if not ok:
            values = parameters.get(self.IMAGES)
            for value in values if isinstance(values, (list, tuple)) else [values]:
                if isinstance(value, str) and QgsProcessingUtils.mapLayerFromString(value, context, False) is None:
                    try:
                        sensors.check_image(value)
                    except PushbroomError as exc:
                        return False, str(exc)
        return ok, message

    def execute(self, parameters, context, feedback):
        dem = self.parameterAsRasterLayer(parameters, self.DEM, context)
        params = CreateParams(
            orientation=self.parameterAsFileList(parameters, self.ORIENTATION, context),
            dem=dem.source() if dem is not None else None,
            **self.parameterValues(
                parameters, context, dem_nodata=self.DEM_NODATA, height=self.HEIGHT, overwrite=self.OVERWRITE
            ),
            execution=execution_choice(self, parameters, context),
        )
        images = [layer.source() for layer in self.parameterAsLayerList(parameters, self.IMAGES, context)]
        result = create_block(self.parameterAsFileOutput(parameters, self.OUTPUT, context), images, params, feedback)
        load_styled(context, result.footprints, "Footprints", self.FOOTPRINTS, "footprints.qml")
        return {self.OUTPUT: result.path, self.FOOTPRINTS: result.footprints}
