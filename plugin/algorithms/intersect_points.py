"""pushbroom:intersectpoints: the block's points intersected into a point cloud
(algorithms/steps/block_intersection.py)."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
)

from ...algorithms.steps.block_intersection import MAX_NEIGHBOURS, IntersectParams, intersect_block_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, execution_choice, execution_parameters

Number = QgsProcessingParameterNumber
#: the point sets: (engine key, label)
KINDS = (
    ("mass_points", "Mass points (pushbroom:matchpoints)"),
    ("tie_points", "Tie points (pushbroom:selecttiepoints)"),
)


class IntersectPoints(PushbroomAlgorithm):
    NAME = "intersectpoints"
    DISPLAY_NAME = "Intersect points (point cloud)"
    GROUP_ID = "surface"

    KEYS = (
        "BLOCK POINTS CRS SIGMA MAX_ITERATIONS OUTLIER_NEIGHBOURS OUTLIER_FACTOR EXECUTION DASK_ADDRESS DASK_WAIT "
        "WORKERS OUTPUT LAYER COUNT"
    )

    def initAlgorithm(self, config=None):
        d, tr = IntersectParams(), self.tr
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, tr("Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterEnum(self.POINTS, tr("Points"), [tr(text) for _, text in KINDS], defaultValue=0)
        )
        self.addParameter(
            QgsProcessingParameterCrs(self.CRS, tr("Output CRS (empty: the block's UTM zone)"), None, optional=True)
        )
        self.addAdvancedParameters(
            [
                Number(self.SIGMA, tr("Sigma of the image coordinates (px)"), Number.Double, d.sigma, minValue=1e-6),
                Number(
                    self.MAX_ITERATIONS,
                    tr("Maximum iterations per point"),
                    Number.Integer,
                    d.max_iterations,
                    minValue=1,
                ),
                Number(
                    self.OUTLIER_NEIGHBOURS,
                    tr("Statistical outlier removal: neighbours k (0: off)"),
                    Number.Integer,
                    d.outlier_neighbours,
                    minValue=0,
                    maxValue=MAX_NEIGHBOURS,
                ),
                Number(
                    self.OUTLIER_FACTOR,
                    tr("Statistical outlier removal: factor n (mean distance > mu + n sigma)"),
                    Number.Double,
                    d.outlier_factor,
                    minValue=0.1,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT, tr("Point cloud"), tr("LAS files (*.las);;LAZ files (*.laz);;GeoPackage (*.gpkg)")
            )
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.LAYER, tr("Point layer (GeoPackage output)"), QgsProcessing.TypeVectorPoint
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.COUNT, tr("Points written")))

    def execute(self, parameters, context, feedback):
        values = self.parameterValues(
            parameters,
            context,
            kind=self.POINTS,
            sigma=self.SIGMA,
            max_iterations=self.MAX_ITERATIONS,
            outlier_neighbours=self.OUTLIER_NEIGHBOURS,
            outlier_factor=self.OUTLIER_FACTOR,
        )
        values["kind"] = KINDS[values["kind"]][0]
        params = IntersectParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            execution=execution_choice(self, parameters, context),
            **values,
        )
        result = intersect_block_points(
            self.parameterAsFile(parameters, self.BLOCK, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT, context),
            params,
            feedback,
        )
        if result.layer:
            load_styled(context, result.layer, self.tr("Object points"), self.LAYER, "points_by_group.qml")
        return self.given({self.OUTPUT: result.path, self.COUNT: result.count, self.LAYER: result.layer})
