"""pushbroom:selecttiepoints — the Processing face of steps.block_tie_points.select_block_tie_points:
one tie point per grid cell of the reference image from the block's mass points."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputFile,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
)

from ...algorithms.steps.block_tie_points import TieParams, select_block_tie_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, replace_fewer_parameter

Number = QgsProcessingParameterNumber


class SelectTiePoints(PushbroomAlgorithm):
    NAME = "selecttiepoints"
    DISPLAY_NAME = "Select tie points"
    GROUP_ID = "matching"

    KEYS = "BLOCK CELL MIN_GROUP REPLACE_FEWER TIE_POINTS TIE_POINTS_FILE"

    def initAlgorithm(self, config=None):
        d, tr = TieParams(), self.tr
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, tr("Block"), extension="gpkg"))
        self.addParameter(
            Number(self.CELL, tr("Grid cell size (px of the reference image)"), Number.Double, d.cell, minValue=1.0)
        )
        self.addParameter(
            Number(
                self.MIN_GROUP,
                tr("Lowest point group accepted (1, 2 or 3)"),
                Number.Integer,
                d.min_group,
                minValue=1,
                maxValue=3,
            )
        )
        self.addAdvancedParameters([replace_fewer_parameter(self, tr("tie points"))])
        self.addOutput(QgsProcessingOutputVectorLayer(self.TIE_POINTS, tr("Tie points"), QgsProcessing.TypeVectorPoint))
        self.addOutput(QgsProcessingOutputFile(self.BLOCK, tr("Block (updated; chains the next step in a model)")))
        self.addOutput(QgsProcessingOutputFile(self.TIE_POINTS_FILE, tr("Tie point folder (index and parts)")))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = TieParams(
            **self.parameterValues(
                parameters, context, cell=self.CELL, min_group=self.MIN_GROUP, replace_fewer=self.REPLACE_FEWER
            )
        )
        result = select_block_tie_points(path, params, feedback)
        load_styled(context, result.layer, "Tie points", self.TIE_POINTS, "points_by_group.qml")
        return {self.BLOCK: path, self.TIE_POINTS: result.layer, self.TIE_POINTS_FILE: result.sidecar}
