"""pushbroom:orthorectify: orthoimage of one image on a DEM (algorithms/ortho/orthorectify.py)."""

from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.dem_store import VERTICAL
from ...algorithms.ortho import OrthoOutputs
from ...algorithms.ortho.resampling import METHODS
from ...algorithms.steps.orthoimage import OrthoParams, orthorectify_image
from ..styles import style_on_completion
from .base import PushbroomAlgorithm, cog_parameter, execution_choice, execution_parameters, translate, translated
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber
#: the resampling methods (ortho.resampling.METHODS) and their labels
RESAMPLING = tuple(METHODS)
RESAMPLING_LABELS = {
    "bilinear": QT_TRANSLATE_NOOP("Pushbroom", "Bilinear"),
    "bicubic": QT_TRANSLATE_NOOP("Pushbroom", "Bicubic"),
}
#: labels of the DEM's vertical references (algorithms/dem_store.py VERTICAL, in that order)
DEM_HEIGHTS = (QT_TRANSLATE_NOOP("Pushbroom", "ellipsoidal (WGS 84)"), QT_TRANSLATE_NOOP("Pushbroom", "EGM96"))


class Orthorectify(PushbroomAlgorithm):
    NAME = "orthorectify"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Orthorectify image")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    IMAGE_NAME = "IMAGE_NAME"
    IMAGE = "IMAGE"
    ORIENTATION = "ORIENTATION"
    DEM = "DEM"
    DEM_HEIGHTS = "DEM_HEIGHTS"
    CRS = "CRS"
    CELL_SIZE = "CELL_SIZE"
    RESAMPLING = "RESAMPLING"
    OCCLUSION = "OCCLUSION"
    MAX_ERROR = "MAX_ERROR"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    DEM_NODATA = "DEM_NODATA"
    COG = "COG"
    OUTPUT = "OUTPUT"
    OCCLUSIONS = "OCCLUSIONS"
    BOUND = "BOUND"
    CELLS = "CELLS"

    def initAlgorithm(self, config=None):
        d = OrthoParams()
        self.addParameter(
            QgsProcessingParameterFile(
                self.BLOCK,
                translate("Pushbroom", "Block (empty: the image's own orientation)"),
                extension="gpkg",
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterString(
                self.IMAGE_NAME, translate("Pushbroom", "Image name in the block"), optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterLayer(
                self.IMAGE, translate("Pushbroom", "Image (without a block)"), optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterFile(
                self.ORIENTATION,
                translate("Pushbroom", "Orientation file (empty: found beside the image)"),
                optional=True,
            )
        )
        self.addParameter(QgsProcessingParameterRasterLayer(self.DEM, translate("Pushbroom", "DEM")))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.DEM_HEIGHTS,
                translate("Pushbroom", "DEM heights"),
                [translated(label) for label in DEM_HEIGHTS],
                defaultValue=0,
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, translate("Pushbroom", "Output CRS (empty: UTM zone of the footprint)"), None, optional=True
            )
        )
        self.addParameter(
            Number(
                self.CELL_SIZE,
                translate("Pushbroom", "Cell size in CRS units (empty: ground sampling distance)"),
                Number.Double,
                None,
                optional=True,
                minValue=0.0,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.RESAMPLING,
                translate("Pushbroom", "Resampling"),
                [translated(RESAMPLING_LABELS.get(m, m)) for m in RESAMPLING],
                defaultValue=0,
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.OCCLUSION, translate("Pushbroom", "Occluded cells as nodata"), d.occlusion
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.MAX_ERROR,
                    translate("Pushbroom", "Bound of the coarse-grid interpolation error (px)"),
                    Number.Double,
                    d.max_error,
                    minValue=1e-6,
                ),
                *execution_parameters(self, d.execution.workers),
                nodata_parameter(self.DEM_NODATA),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, translate("Pushbroom", "Orthoimage")))
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.OCCLUSIONS,
                translate("Pushbroom", "Occlusion mask (0 seen, 1 occluded by the DEM's surface, 255 outside)"),
                optional=True,
                createByDefault=False,
            )
        )
        self.addOutput(
            QgsProcessingOutputNumber(self.BOUND, translate("Pushbroom", "Achieved interpolation error bound (px)"))
        )
        self.addOutput(QgsProcessingOutputNumber(self.CELLS, translate("Pushbroom", "Cells with image values")))

    def ortho_params(self, parameters, context):
        """OrthoParams of the parameters."""
        values = self.parameterValues(
            parameters,
            context,
            dem_heights=self.DEM_HEIGHTS,
            dem_nodata=self.DEM_NODATA,
            cell_size=self.CELL_SIZE,
            resampling=self.RESAMPLING,
            occlusion=self.OCCLUSION,
            max_error=self.MAX_ERROR,
        )
        values.update(dem_heights=VERTICAL[values["dem_heights"]], resampling=RESAMPLING[values["resampling"]])
        return OrthoParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            execution=execution_choice(self, parameters, context),
            cog=self.parameterAsBool(parameters, self.COG, context),
            **values,
        )

    def execute(self, parameters, context, feedback):
        params = self.ortho_params(parameters, context)
        image = self.parameterAsRasterLayer(parameters, self.IMAGE, context)
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        occlusions = self.parameterAsOutputLayer(parameters, self.OCCLUSIONS, context) or None
        result = orthorectify_image(
            OrthoOutputs(output, occlusions),
            self.parameterAsRasterLayer(parameters, self.DEM, context).source(),
            params,
            block_path=self.parameterAsFile(parameters, self.BLOCK, context),
            image_name=self.parameterAsString(parameters, self.IMAGE_NAME, context),
            image=image.source() if image is not None else None,
            orientation=self.parameterAsFile(parameters, self.ORIENTATION, context),
            feedback=feedback,
        )
        if occlusions:
            style_on_completion(context, occlusions, "occlusions.qml")
        return self.given(
            {self.OUTPUT: output, self.OCCLUSIONS: occlusions, self.BOUND: result.bound, self.CELLS: result.cells}
        )
