"""pushbroom:selecttiepoints — the Processing face of steps.block_tie_points.select_block_tie_points:
one tie point per grid cell of the reference image from the block's mass points."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputFile,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.steps.block_tie_points import TieParams, select_block_tie_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, replace_fewer_parameter, translate

Number = QgsProcessingParameterNumber


class SelectTiePoints(PushbroomAlgorithm):
    NAME = "selecttiepoints"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Select tie points")
    GROUP_ID = "matching"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    CELL = "CELL"
    MIN_GROUP = "MIN_GROUP"
    REPLACE_FEWER = "REPLACE_FEWER"
    TIE_POINTS = "TIE_POINTS"
    TIE_POINTS_FILE = "TIE_POINTS_FILE"

    def initAlgorithm(self, config=None):
        d = TieParams()
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            Number(
                self.CELL,
                translate("Pushbroom", "Grid cell size (px of the reference image)"),
                Number.Double,
                d.cell,
                minValue=1.0,
            )
        )
        self.addParameter(
            Number(
                self.MIN_GROUP,
                translate("Pushbroom", "Lowest point group accepted (1, 2 or 3)"),
                Number.Integer,
                d.min_group,
                minValue=1,
                maxValue=3,
            )
        )
        self.addAdvancedParameters([replace_fewer_parameter(self, translate("Pushbroom", "tie points"))])
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.TIE_POINTS, translate("Pushbroom", "Tie points"), QgsProcessing.TypeVectorPoint
            )
        )
        self.addOutput(
            QgsProcessingOutputFile(
                self.BLOCK, translate("Pushbroom", "Block (updated; chains the next step in a model)")
            )
        )
        self.addOutput(
            QgsProcessingOutputFile(self.TIE_POINTS_FILE, translate("Pushbroom", "Tie point folder (index and parts)"))
        )

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = TieParams(
            **self.parameterValues(
                parameters, context, cell=self.CELL, min_group=self.MIN_GROUP, replace_fewer=self.REPLACE_FEWER
            )
        )
        result = select_block_tie_points(path, params, feedback)
        load_styled(context, result.layer, "Tie points", self.TIE_POINTS, "points_by_group.qml")
        return {self.BLOCK: path, self.TIE_POINTS: result.layer, self.TIE_POINTS_FILE: result.folder}
