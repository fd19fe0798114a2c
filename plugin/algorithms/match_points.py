"""pushbroom:matchpoints: dense image points of the block (algorithms/steps/block_matching.py)."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputFile,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
)

from ...algorithms.dense.params import DenseParams
from ...algorithms.dense.sgm import SgmParams
from ...algorithms.matching.coarse_to_fine import CoarseToFineParams
from ...algorithms.matching.params import GrowParams
from ...algorithms.matching.region_growing_strategy import RegionGrowingSettings
from ...algorithms.matching_strategies import registered
from ...algorithms.steps.block_matching import MatchParams, match_block_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, execution_choice, execution_parameters, replace_fewer_parameter

Number = QgsProcessingParameterNumber
#: seed choices: (engine key, label)
SEED_SOURCES = (
    ("automatic", "Automatic: interest points matched along the path predicted by the sensor models"),
    ("tie_points", "The block's tie points (pushbroom:selecttiepoints)"),
    ("both", "Both: the block's tie points and automatic seeds"),
)
#: the STRATEGY enum's first entries, in the order saved models hold their indices; other registered strategies
#: follow, with their default settings
FIRST_STRATEGIES = ("region_growing", "coarse_to_fine", "dense")
#: matching strategies: (engine key, label)
STRATEGIES = tuple(
    (name, registered()[name].label)
    for name in sorted(
        registered(), key=lambda n: FIRST_STRATEGIES.index(n) if n in FIRST_STRATEGIES else len(FIRST_STRATEGIES)
    )
)


class MatchPoints(PushbroomAlgorithm):
    NAME = "matchpoints"
    DISPLAY_NAME = "Match points"
    GROUP_ID = "matching"

    KEYS = (
        "BLOCK STRATEGY IMAGES MIN_HEIGHT MAX_HEIGHT SEEDS TEMPLATE STEP WIDE_TEMPLATE RHO_MIN MAX_ELLIPSE "
        "MAX_SHIFT MAX_ITERATIONS TILE SIGMA_FACTOR GROW_SECOND MPGC_REFINE MPGC_SUPPORT "
        "EXECUTION DASK_ADDRESS DASK_WAIT WORKERS COARSE_TO_FINE_GRID COARSE_TO_FINE_RHO_MIN COARSE_TO_FINE_TILE "
        "COARSE_TO_FINE_EDGE_POINTS DENSE_TILE DENSE_STEP DENSE_REFINE DENSE_MPGC DENSE_P1 DENSE_P2 REPLACE_FEWER "
        "SUMMARY POINTS POINTS_FILE"
    )

    def initAlgorithm(self, config=None):
        d, c, m, e = GrowParams(), CoarseToFineParams(), RegionGrowingSettings(), DenseParams()
        execution = MatchParams().execution
        tr = self.tr
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, tr("Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.STRATEGY, tr("Matching strategy"), [tr(label) for _, label in STRATEGIES], defaultValue=0
            )
        )
        self.addParameter(
            QgsProcessingParameterString(
                self.IMAGES,
                tr("Images in combination order: reference (nadir), forward[, backward]; empty = all"),
                "",
                optional=True,
            )
        )
        self.addParameter(
            Number(
                self.MIN_HEIGHT,
                tr("Lowest ellipsoidal terrain height (m; empty: the block's terrain height range)"),
                Number.Double,
                None,
                optional=True,
            )
        )
        self.addParameter(
            Number(
                self.MAX_HEIGHT,
                tr("Highest ellipsoidal terrain height (m; empty: the block's terrain height range)"),
                Number.Double,
                None,
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.SEEDS, tr("Seeds"), [tr(label) for _, label in SEED_SOURCES], defaultValue=0
            )
        )
        self.addParameter(Number(self.TEMPLATE, tr("Template size (px, odd)"), Number.Integer, d.template, minValue=5))
        self.addParameter(
            Number(self.STEP, tr("STEP: distance of the neighbours (px)"), Number.Integer, d.step, minValue=1)
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.WIDE_TEMPLATE,
                    tr("Second, wider template where the first one fails (px, odd; 0 = off)"),
                    Number.Integer,
                    d.wide_template,
                    minValue=0,
                ),
                Number(
                    self.RHO_MIN,
                    tr("Minimum correlation coefficient"),
                    Number.Double,
                    d.rho_min,
                    minValue=0.0,
                    maxValue=1.0,
                ),
                Number(
                    self.MAX_ELLIPSE,
                    tr("Maximum semi-major axis of the error ellipse (px)"),
                    Number.Double,
                    d.max_ellipse,
                    minValue=0.0,
                ),
                Number(
                    self.MAX_SHIFT,
                    tr("Maximum shift from the initial values (px)"),
                    Number.Double,
                    d.max_shift,
                    minValue=0.0,
                ),
                Number(self.MAX_ITERATIONS, tr("Maximum LSM iterations"), Number.Integer, d.max_iterations, minValue=1),
                Number(self.TILE, tr("Tile size of the reference image (px)"), Number.Integer, d.tile, minValue=16),
                Number(
                    self.SIGMA_FACTOR,
                    tr("Group 3 consistency test: deviations below k robust sigma"),
                    Number.Double,
                    m.sigma_factor,
                    minValue=0.1,
                ),
                QgsProcessingParameterBoolean(
                    self.GROW_SECOND, tr("Also grow combination (b) where (a) found no points"), m.grow_second
                ),
                QgsProcessingParameterBoolean(
                    self.MPGC_REFINE, tr("Refine the group 3 points by MPGC (three images)"), m.mpgc
                ),
                QgsProcessingParameterBoolean(
                    self.MPGC_SUPPORT,
                    tr("MPGC refinement with support weights (heights of the template centre's surface; for DEMs)"),
                    d.support_weights,
                ),
                *execution_parameters(self, execution.workers),
                Number(
                    self.COARSE_TO_FINE_GRID,
                    tr("Coarse-to-fine: grid point spacing at full resolution (px)"),
                    Number.Integer,
                    c.grid,
                    minValue=2,
                ),
                Number(
                    self.COARSE_TO_FINE_RHO_MIN,
                    tr("Coarse-to-fine: minimum correlation coefficient at full resolution"),
                    Number.Double,
                    c.rho_min,
                    minValue=0.0,
                    maxValue=1.0,
                ),
                Number(
                    self.COARSE_TO_FINE_TILE,
                    tr("Coarse-to-fine: tile size of the reference image (px)"),
                    Number.Integer,
                    c.tile,
                    minValue=16,
                ),
                QgsProcessingParameterBoolean(
                    self.COARSE_TO_FINE_EDGE_POINTS,
                    tr("Coarse-to-fine: matched edges as extra points and breaklines (off: blunders on steep forest)"),
                    c.edge_points,
                ),
                Number(
                    self.DENSE_TILE,
                    tr("Dense: tile size of the reference image (px)"),
                    Number.Integer,
                    e.tile,
                    minValue=64,
                    maxValue=4096,
                ),
                Number(
                    self.DENSE_STEP,
                    tr("Dense: a point every ... px of the reference image"),
                    Number.Integer,
                    e.step,
                    minValue=1,
                ),
                QgsProcessingParameterBoolean(
                    self.DENSE_REFINE,
                    tr("Dense: refine the positions by LSM in the original images (TEMPLATE px)"),
                    e.lsm,
                ),
                QgsProcessingParameterBoolean(
                    self.DENSE_MPGC,
                    tr(
                        "Dense: refine a triplet's three-ray points by MPGC "
                        "(more and better points, matching about 4x slower)"
                    ),
                    e.mpgc,
                ),
                Number(
                    self.DENSE_P1,
                    tr("Dense: SGM penalty P1 (a disparity change of 1 px)"),
                    Number.Double,
                    e.sgm.p1,
                    minValue=0.0,
                ),
                Number(
                    self.DENSE_P2, tr("Dense: SGM penalty P2 (a larger change)"), Number.Double, e.sgm.p2, minValue=0.0
                ),
                replace_fewer_parameter(self, tr("mass points")),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.SUMMARY, tr("Summary per point group (CSV)"), tr("CSV files (*.csv)"), optional=True
            )
        )
        self.addOutput(QgsProcessingOutputVectorLayer(self.POINTS, tr("Mass points"), QgsProcessing.TypeVectorPoint))
        self.addOutput(QgsProcessingOutputFile(self.BLOCK, tr("Block (updated; chains the next step in a model)")))
        self.addOutput(QgsProcessingOutputFile(self.POINTS_FILE, tr("Mass point folder (index and parts)")))

    def match_params(self, parameters, context):
        """MatchParams of the parameters: the chosen strategy's settings of its parameters."""
        values = self.parameterValues(
            parameters,
            context,
            images=self.IMAGES,
            min_height=self.MIN_HEIGHT,
            max_height=self.MAX_HEIGHT,
            strategy=self.STRATEGY,
            replace_fewer=self.REPLACE_FEWER,
        )
        strategy = STRATEGIES[values.pop("strategy")][0]
        settings = {
            "region_growing": self.region_growing_settings,
            "coarse_to_fine": self.coarse_to_fine_settings,
            "dense": self.dense_settings,
        }.get(strategy)
        return MatchParams(
            strategy=strategy,
            settings=settings(parameters, context) if settings else None,
            execution=execution_choice(self, parameters, context),
            **values,
        )

    def region_growing_settings(self, parameters, context):
        grow = GrowParams(
            **self.parameterValues(
                parameters,
                context,
                template=self.TEMPLATE,
                wide_template=self.WIDE_TEMPLATE,
                step=self.STEP,
                rho_min=self.RHO_MIN,
                max_ellipse=self.MAX_ELLIPSE,
                max_shift=self.MAX_SHIFT,
                max_iterations=self.MAX_ITERATIONS,
                tile=self.TILE,
                support_weights=self.MPGC_SUPPORT,
            )
        )
        values = self.parameterValues(
            parameters,
            context,
            seeds=self.SEEDS,
            sigma_factor=self.SIGMA_FACTOR,
            grow_second=self.GROW_SECOND,
            mpgc=self.MPGC_REFINE,
        )
        values.update(seeds=SEED_SOURCES[values["seeds"]][0])
        return RegionGrowingSettings(grow=grow, **values)

    def coarse_to_fine_settings(self, parameters, context):
        return CoarseToFineParams(
            **self.parameterValues(
                parameters,
                context,
                grid=self.COARSE_TO_FINE_GRID,
                rho_min=self.COARSE_TO_FINE_RHO_MIN,
                tile=self.COARSE_TO_FINE_TILE,
                edge_points=self.COARSE_TO_FINE_EDGE_POINTS,
            )
        )

    def dense_settings(self, parameters, context):
        dense = self.parameterValues(
            parameters,
            context,
            tile=self.DENSE_TILE,
            step=self.DENSE_STEP,
            lsm=self.DENSE_REFINE,
            mpgc=self.DENSE_MPGC,
            template=self.TEMPLATE,
        )
        sgm = SgmParams(**self.parameterValues(parameters, context, p1=self.DENSE_P1, p2=self.DENSE_P2))
        return DenseParams(sgm=sgm, **dense)

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        result = match_block_points(
            path,
            self.match_params(parameters, context),
            self.parameterAsFileOutput(parameters, self.SUMMARY, context) or None,
            feedback,
        )
        out = {self.BLOCK: path, self.POINTS: result.layer, self.POINTS_FILE: result.folder}
        if result.summary_csv:
            out[self.SUMMARY] = result.summary_csv
        load_styled(context, result.layer, self.tr("Mass points"), self.POINTS, "points_by_group.qml")
        return out
