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

from ...algorithms.dem_store import VERTICAL
from ...algorithms.ortho.resampling import METHODS
from ...algorithms.steps.orthoimage import OrthoParams, orthorectify_image
from .base import PushbroomAlgorithm, execution_choice, execution_parameters
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber
RESAMPLING = tuple(METHODS)
#: labels of the DEM's vertical references (algorithms/dem_store.py VERTICAL, in that order)
DEM_HEIGHTS = ("ellipsoidal (WGS 84)", "EGM96")


class Orthorectify(PushbroomAlgorithm):
    NAME = "orthorectify"
    DISPLAY_NAME = "Orthorectify image"
    GROUP_ID = "surface"

    KEYS = (
        "BLOCK IMAGE_NAME IMAGE ORIENTATION DEM DEM_HEIGHTS CRS CELL_SIZE RESAMPLING OCCLUSION MAX_ERROR "
        "EXECUTION DASK_ADDRESS DASK_WAIT WORKERS DEM_NODATA OUTPUT BOUND CELLS"
    )

    def initAlgorithm(self, config=None):
        d, tr = OrthoParams(), self.tr
        self.addParameter(
            QgsProcessingParameterFile(
                self.BLOCK, tr("Block (empty: the image's own orientation)"), extension="gpkg", optional=True
            )
        )
        self.addParameter(QgsProcessingParameterString(self.IMAGE_NAME, tr("Image name in the block"), optional=True))
        self.addParameter(QgsProcessingParameterRasterLayer(self.IMAGE, tr("Image (without a block)"), optional=True))
        self.addParameter(
            QgsProcessingParameterFile(
                self.ORIENTATION, tr("Orientation file (empty: found beside the image)"), optional=True
            )
        )
        self.addParameter(QgsProcessingParameterRasterLayer(self.DEM, tr("DEM")))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.DEM_HEIGHTS, tr("DEM heights"), [tr(label) for label in DEM_HEIGHTS], defaultValue=0
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, tr("Output CRS (empty: UTM zone of the footprint)"), None, optional=True
            )
        )
        self.addParameter(
            Number(
                self.CELL_SIZE,
                tr("Cell size in CRS units (empty: ground sampling distance)"),
                Number.Double,
                None,
                optional=True,
                minValue=0.0,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(self.RESAMPLING, tr("Resampling"), list(RESAMPLING), defaultValue=0)
        )
        self.addParameter(QgsProcessingParameterBoolean(self.OCCLUSION, tr("Occluded cells as nodata"), d.occlusion))
        self.addAdvancedParameters(
            [
                Number(
                    self.MAX_ERROR,
                    tr("Bound of the coarse-grid interpolation error (px)"),
                    Number.Double,
                    d.max_error,
                    minValue=1e-6,
                ),
                *execution_parameters(self, d.execution.workers),
                nodata_parameter(self.DEM_NODATA),
            ]
        )
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("Orthoimage")))
        self.addOutput(QgsProcessingOutputNumber(self.BOUND, tr("Achieved interpolation error bound (px)")))
        self.addOutput(QgsProcessingOutputNumber(self.CELLS, tr("Cells with image values")))

    def execute(self, parameters, context, feedback):
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
        params = OrthoParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            execution=execution_choice(self, parameters, context),
            **values,
        )
        image = self.parameterAsRasterLayer(parameters, self.IMAGE, context)
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        result = orthorectify_image(
            output,
            self.parameterAsRasterLayer(parameters, self.DEM, context).source(),
            params,
            block_path=self.parameterAsFile(parameters, self.BLOCK, context),
            image_name=self.parameterAsString(parameters, self.IMAGE_NAME, context),
            image=image.source() if image is not None else None,
            orientation=self.parameterAsFile(parameters, self.ORIENTATION, context),
            feedback=feedback,
        )
        return {self.OUTPUT: output, self.BOUND: result.bound, self.CELLS: result.cells}
