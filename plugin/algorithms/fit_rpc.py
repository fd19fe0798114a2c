"""pushbroom:fitrpc — the Processing face of steps.block_rpcs.fit_block_rpcs: RPC00B fitted to the
block's sensor models, written as _RPC.TXT files GDAL reads."""

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputMultipleLayers,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.height_range import PLAUSIBLE_HEIGHTS
from ...algorithms.steps.block_rpcs import RpcParams, fit_block_rpcs
from .base import PushbroomAlgorithm, translate

Number = QgsProcessingParameterNumber


class FitRpc(PushbroomAlgorithm):
    NAME = "fitrpc"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Fit RPC")
    GROUP_ID = "adjustment"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    IMAGE = "IMAGE"
    MIN_HEIGHT = "MIN_HEIGHT"
    MAX_HEIGHT = "MAX_HEIGHT"
    OVERWRITE = "OVERWRITE"
    GRID = "GRID"
    HEIGHT_LEVELS = "HEIGHT_LEVELS"
    OUTPUT_FOLDER = "OUTPUT_FOLDER"
    REPORT = "REPORT"
    FILES = "FILES"

    def initAlgorithm(self, config=None):
        d = RpcParams()
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterString(
                self.IMAGE,
                translate("Pushbroom", "Image name (empty: every image of the block)"),
                d.image,
                optional=True,
            )
        )
        self.addParameter(
            Number(
                self.MIN_HEIGHT,
                translate(
                    "Pushbroom", "Lowest ellipsoidal height of the cube (m, {:g} .. {:g}; empty: the block's)"
                ).format(*PLAUSIBLE_HEIGHTS),
                Number.Double,
                None,
                optional=True,
            )
        )
        self.addParameter(
            Number(
                self.MAX_HEIGHT,
                translate(
                    "Pushbroom", "Highest ellipsoidal height of the cube (m, {:g} .. {:g}; empty: the block's)"
                ).format(*PLAUSIBLE_HEIGHTS),
                Number.Double,
                None,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.OVERWRITE,
                translate("Pushbroom", "Overwrite existing _RPC.TXT files, also beside an image with its own RPC"),
                d.overwrite,
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.GRID,
                    translate("Pushbroom", "Image grid points along columns and rows"),
                    Number.Integer,
                    d.grid,
                    minValue=4,
                ),
                Number(
                    self.HEIGHT_LEVELS,
                    translate("Pushbroom", "Height levels"),
                    Number.Integer,
                    d.height_levels,
                    minValue=4,
                ),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFolderDestination(
                self.OUTPUT_FOLDER,
                translate(
                    "Pushbroom", "Output folder (empty: beside each image raster, where it carries no RPC of its own)"
                ),
                optional=True,
                createByDefault=False,
            )
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.REPORT,
                translate("Pushbroom", "Report"),
                translate("Pushbroom", "HTML files (*.html)"),
                optional=True,
            )
        )
        self.addOutput(QgsProcessingOutputMultipleLayers(self.FILES, translate("Pushbroom", "RPC files (_RPC.TXT)")))
        self.addOutput(
            QgsProcessingOutputFile(
                self.BLOCK, translate("Pushbroom", "Block (updated; chains the next step in a model)")
            )
        )

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = RpcParams(
            folder=self.parameterAsString(parameters, self.OUTPUT_FOLDER, context) or None,
            report=self.parameterAsFileOutput(parameters, self.REPORT, context) or None,
            **self.parameterValues(
                parameters,
                context,
                image=self.IMAGE,
                min_height=self.MIN_HEIGHT,
                max_height=self.MAX_HEIGHT,
                overwrite=self.OVERWRITE,
                grid=self.GRID,
                height_levels=self.HEIGHT_LEVELS,
            ),
        )
        result = fit_block_rpcs(path, params, feedback)
        return self.given(
            {self.BLOCK: path, self.FILES: result.files, self.OUTPUT_FOLDER: params.folder, self.REPORT: result.report}
        )
