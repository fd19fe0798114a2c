"""pushbroom:intersectpoints: the block's points intersected into a point cloud
(algorithms/steps/block_intersection.py)."""

import os

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.steps.block_intersection import MAX_NEIGHBOURS, IntersectParams, intersect_block_points
from ..styles import load_point_cloud, load_styled
from .base import PushbroomAlgorithm, execution_choice, execution_parameters, translate, translated

Number = QgsProcessingParameterNumber
#: the point sets: (engine key, label)
KINDS = (
    ("mass_points", QT_TRANSLATE_NOOP("Pushbroom", "Mass points (pushbroom:matchpoints)")),
    ("tie_points", QT_TRANSLATE_NOOP("Pushbroom", "Tie points (pushbroom:selecttiepoints)")),
)


class IntersectPoints(PushbroomAlgorithm):
    NAME = "intersectpoints"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Intersect points (point cloud)")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    POINTS = "POINTS"
    CRS = "CRS"
    SIGMA = "SIGMA"
    MAX_ITERATIONS = "MAX_ITERATIONS"
    OUTLIER_NEIGHBOURS = "OUTLIER_NEIGHBOURS"
    OUTLIER_FACTOR = "OUTLIER_FACTOR"
    COLOUR = "COLOUR"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    OUTPUT = "OUTPUT"
    EPT = "EPT"
    #: the EPT folder is replaced as a whole where it holds an EPT index (its ept.json)
    WHOLE_FOLDERS = {EPT: "ept.json"}
    LAYER = "LAYER"
    COUNT = "COUNT"

    def initAlgorithm(self, config=None):
        d = IntersectParams()
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.POINTS, translate("Pushbroom", "Points"), [translated(text) for _, text in KINDS], defaultValue=0
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, translate("Pushbroom", "Output CRS (empty: the block's UTM zone)"), None, optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.COLOUR,
                translate("Pushbroom", "Colour the points from the images (LAS colour fields)"),
                d.colour,
                optional=True,  # the models saved before it still validate
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.SIGMA,
                    translate("Pushbroom", "Sigma of the image coordinates (px)"),
                    Number.Double,
                    d.sigma,
                    minValue=1e-6,
                ),
                Number(
                    self.MAX_ITERATIONS,
                    translate("Pushbroom", "Maximum iterations per point"),
                    Number.Integer,
                    d.max_iterations,
                    minValue=1,
                ),
                Number(
                    self.OUTLIER_NEIGHBOURS,
                    translate("Pushbroom", "Statistical outlier removal: neighbours k (0: off)"),
                    Number.Integer,
                    d.outlier_neighbours,
                    minValue=0,
                    maxValue=MAX_NEIGHBOURS,
                ),
                Number(
                    self.OUTLIER_FACTOR,
                    translate("Pushbroom", "Statistical outlier removal: factor n (mean distance > mu + n sigma)"),
                    Number.Double,
                    d.outlier_factor,
                    minValue=0.1,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT,
                translate("Pushbroom", "Point cloud"),
                translate("Pushbroom", "LAS files (*.las);;LAZ files (*.laz);;GeoPackage (*.gpkg)"),
            )
        )
        self.addParameter(
            QgsProcessingParameterFolderDestination(
                self.EPT,
                translate("Pushbroom", "EPT index of the point cloud (opens in QGIS without PDAL)"),
                optional=True,
                createByDefault=False,
            )
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.LAYER, translate("Pushbroom", "Point layer (GeoPackage output)"), QgsProcessing.TypeVectorPoint
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.COUNT, translate("Pushbroom", "Points written")))

    def intersect_params(self, parameters, context):
        """IntersectParams of the parameters."""
        values = self.parameterValues(
            parameters,
            context,
            kind=self.POINTS,
            sigma=self.SIGMA,
            max_iterations=self.MAX_ITERATIONS,
            outlier_neighbours=self.OUTLIER_NEIGHBOURS,
            outlier_factor=self.OUTLIER_FACTOR,
            colour=self.COLOUR,
        )
        values["kind"] = KINDS[values["kind"]][0]
        return IntersectParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            execution=execution_choice(self, parameters, context),
            **values,
        )

    def execute(self, parameters, context, feedback):
        params = self.intersect_params(parameters, context)
        result = intersect_block_points(
            self.parameterAsFile(parameters, self.BLOCK, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT, context),
            params,
            feedback,
            self.parameterAsString(parameters, self.EPT, context) or None,
        )
        if result.ept and not load_point_cloud(
            context, result.ept, translate("Pushbroom", "Object points (EPT)"), self.EPT
        ):
            feedback.pushWarning(f"QGIS could not open the EPT index {result.ept} (its ept provider): it is not loaded")
        if result.layer:
            load_styled(
                context, result.layer, translate("Pushbroom", "Object points"), self.LAYER, "points_by_group.qml"
            )
        done = {self.OUTPUT: result.path, self.COUNT: result.count, self.LAYER: result.layer}
        if result.ept:
            done[self.EPT] = os.path.dirname(result.ept)
        return self.given(done)
