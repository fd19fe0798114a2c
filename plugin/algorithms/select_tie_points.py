"""pushbroom:selecttiepoints — one tie point per grid cell of the reference image from the
block's mass points (algorithms/matching/tiepoints.py)."""
from qgis.core import (QgsProcessing, QgsProcessingOutputFile, QgsProcessingOutputVectorLayer,
                       QgsProcessingParameterFile, QgsProcessingParameterNumber)

from ...algorithms.block import Block
from ...algorithms.matching.tiepoints import select_tie_points
from .base import PushbroomAlgorithm
from ..styles import load_styled
from ...algorithms.height_range import mean_height

Number = QgsProcessingParameterNumber


class SelectTiePoints(PushbroomAlgorithm):
    NAME = "selecttiepoints"
    DISPLAY_NAME = "Select tie points"
    GROUP = "Matching"
    GROUP_ID = "matching"
    HELP = ("Selects tie points for the bundle adjustment from the block's mass points (Kornus et al. 2006, "
            "3.3): one point per regular grid cell of the reference image, the one with the highest "
            "correlation coefficient among the most reliable point group present in the cell (group 3 before "
            "2 before 1). The tie points are stored with the block (<block>.tie_points.npz, referenced in "
            "block_info) and written as the point layer 'tie_points'.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(Number("CELL", "Grid cell size (px of the reference image)", Number.Double, 100.0,
                                 minValue=1.0))
        self.addParameter(Number("MIN_GROUP", "Lowest point group accepted (1, 2 or 3)", Number.Integer, 1,
                                 minValue=1, maxValue=3))
        self.addOutput(QgsProcessingOutputVectorLayer("TIE_POINTS", "Tie points", QgsProcessing.TypeVectorPoint))
        self.addOutput(QgsProcessingOutputFile("BLOCK", "Block (updated; chains the next step in a model)"))
        self.addOutput(QgsProcessingOutputFile("TIE_POINTS_FILE", "Tie point file (.npz)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        mass = blk.points("mass_points")
        tie = select_tie_points(mass, cell=self.parameterAsDouble(parameters, "CELL", context),
                                min_group=self.parameterAsInt(parameters, "MIN_GROUP", context))
        reference = tie.stats.get("tie_reference", (mass.stats.get("images") or [1])[0])
        counts = tie.group_counts()
        feedback.pushInfo(f"{len(tie)} tie points from {len(mass)} mass points: "
                          + ", ".join(f"group {g}: {n}" for g, n in counts.items()))
        npz = blk.save_points(tie, "tie_points", display=(
            blk.model(reference), reference, mean_height(blk.height_range())))
        layer = blk.layer_source("tie_points")
        load_styled(context, layer, "Tie points", "TIE_POINTS", "points_by_group.qml")
        return {"BLOCK": path, "TIE_POINTS": layer, "TIE_POINTS_FILE": npz}
