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
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.dense.params import DenseParams
from ...algorithms.dense.sgm import SgmParams
from ...algorithms.matching.coarse_to_fine import CoarseToFineParams
from ...algorithms.matching.params import GrowParams
from ...algorithms.matching.region_growing_strategy import RegionGrowingSettings
from ...algorithms.matching_strategies import registered
from ...algorithms.steps.block_matching import MatchParams, match_block_points
from ..styles import load_styled
from .base import (
    PushbroomAlgorithm,
    execution_choice,
    execution_parameters,
    replace_fewer_parameter,
    translate,
    translated,
)

Number = QgsProcessingParameterNumber
#: seed choices: (engine key, label)
SEED_SOURCES = (
    (
        "automatic",
        QT_TRANSLATE_NOOP(
            "Pushbroom", "Automatic: interest points matched along the path predicted by the sensor models"
        ),
    ),
    ("tie_points", QT_TRANSLATE_NOOP("Pushbroom", "The block's tie points (pushbroom:selecttiepoints)")),
    ("both", QT_TRANSLATE_NOOP("Pushbroom", "Both: the block's tie points and automatic seeds")),
)
#: the STRATEGY enum's first entries, in the order saved models hold their indices, with their labels; other
#: registered strategies follow under their name, with their default settings
FIRST_STRATEGIES = {
    "region_growing": QT_TRANSLATE_NOOP("Pushbroom", "Region growing (Otto & Chau; Kornus et al. 2006)"),
    "coarse_to_fine": QT_TRANSLATE_NOOP("Pushbroom", "Coarse-to-fine multi-primitive with MPGC (Zhang & Gruen)"),
    "dense": QT_TRANSLATE_NOOP("Pushbroom", "Dense: semi-global matching on epipolar tiles, refined by LSM"),
}
#: matching strategies: (engine key, label)
STRATEGIES = tuple(
    (name, FIRST_STRATEGIES.get(name, name.replace("_", " ")))
    for name in sorted(registered(), key=lambda n: list(FIRST_STRATEGIES).index(n) if n in FIRST_STRATEGIES else 3)
)


class MatchPoints(PushbroomAlgorithm):
    NAME = "matchpoints"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Match points")
    GROUP_ID = "matching"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    STRATEGY = "STRATEGY"
    IMAGES = "IMAGES"
    MIN_HEIGHT = "MIN_HEIGHT"
    MAX_HEIGHT = "MAX_HEIGHT"
    SEEDS = "SEEDS"
    TEMPLATE = "TEMPLATE"
    STEP = "STEP"
    WIDE_TEMPLATE = "WIDE_TEMPLATE"
    RHO_MIN = "RHO_MIN"
    MAX_ELLIPSE = "MAX_ELLIPSE"
    MAX_SHIFT = "MAX_SHIFT"
    MAX_ITERATIONS = "MAX_ITERATIONS"
    TILE = "TILE"
    SIGMA_FACTOR = "SIGMA_FACTOR"
    GROW_SECOND = "GROW_SECOND"
    MPGC_REFINE = "MPGC_REFINE"
    MPGC_SUPPORT = "MPGC_SUPPORT"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    COARSE_TO_FINE_GRID = "COARSE_TO_FINE_GRID"
    COARSE_TO_FINE_RHO_MIN = "COARSE_TO_FINE_RHO_MIN"
    COARSE_TO_FINE_TILE = "COARSE_TO_FINE_TILE"
    COARSE_TO_FINE_EDGE_POINTS = "COARSE_TO_FINE_EDGE_POINTS"
    DENSE_TILE = "DENSE_TILE"
    DENSE_STEP = "DENSE_STEP"
    DENSE_REFINE = "DENSE_REFINE"
    DENSE_WIDE_TEMPLATE = "DENSE_WIDE_TEMPLATE"
    DENSE_MPGC = "DENSE_MPGC"
    DENSE_P1 = "DENSE_P1"
    DENSE_P2 = "DENSE_P2"
    REPLACE_FEWER = "REPLACE_FEWER"
    SUMMARY = "SUMMARY"
    POINTS = "POINTS"
    POINTS_FILE = "POINTS_FILE"

    def initAlgorithm(self, config=None):
        """The parameters in groups: the stereo set and the strategy; each strategy's own (labelled with its name;
        region growing's first three in the main dialog, the rest folded away as advanced); where the tiles run."""
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.STRATEGY,
                translate("Pushbroom", "Matching strategy"),
                [translated(label) for _, label in STRATEGIES],
                defaultValue=0,
            )
        )
        self.addParameter(
            QgsProcessingParameterString(
                self.IMAGES,
                translate("Pushbroom", "Images: reference (nadir), forward[, backward]; empty: all"),
                "",
                optional=True,
            )
        )
        for key, label in (
            (self.MIN_HEIGHT, translate("Pushbroom", "Lowest ellipsoidal terrain height (m; empty: the block's)")),
            (self.MAX_HEIGHT, translate("Pushbroom", "Highest ellipsoidal terrain height (m; empty: the block's)")),
        ):
            self.addParameter(Number(key, label, Number.Double, None, optional=True))
        main, advanced = self.region_growing_parameters()
        for parameter in main:
            self.addParameter(parameter)
        self.addAdvancedParameters(
            [
                *advanced,
                *self.coarse_to_fine_parameters(),
                *self.dense_parameters(),
                *execution_parameters(self, MatchParams().execution.workers),
                replace_fewer_parameter(self, translate("Pushbroom", "mass points")),
            ]
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.SUMMARY,
                translate("Pushbroom", "Summary per point group (CSV)"),
                translate("Pushbroom", "CSV files (*.csv)"),
                optional=True,
            )
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.POINTS, translate("Pushbroom", "Mass points"), QgsProcessing.TypeVectorPoint
            )
        )
        self.addOutput(
            QgsProcessingOutputFile(
                self.BLOCK, translate("Pushbroom", "Block (updated; chains the next step in a model)")
            )
        )
        self.addOutput(
            QgsProcessingOutputFile(self.POINTS_FILE, translate("Pushbroom", "Mass point folder (index and parts)"))
        )

    def region_growing_parameters(self):
        """(main, advanced) parameters of region growing (RegionGrowingSettings; TEMPLATE is dense's too)."""
        d, m = GrowParams(), RegionGrowingSettings()
        main = [
            QgsProcessingParameterEnum(
                self.SEEDS,
                translate("Pushbroom", "Region growing: seeds"),
                [translated(label) for _, label in SEED_SOURCES],
                defaultValue=0,
            ),
            Number(
                self.TEMPLATE,
                translate("Pushbroom", "LSM template size (px, odd; region growing, dense)"),
                Number.Integer,
                d.template,
                minValue=5,
            ),
            Number(
                self.STEP,
                translate("Pushbroom", "Region growing: STEP, the distance of the neighbours (px)"),
                Number.Integer,
                d.step,
                minValue=1,
            ),
        ]
        advanced = [
            Number(
                self.WIDE_TEMPLATE,
                translate("Pushbroom", "Region growing: a wider template where the first fails (px; 0: off)"),
                Number.Integer,
                d.wide_template,
                minValue=0,
            ),
            Number(
                self.RHO_MIN,
                translate("Pushbroom", "Region growing: minimum correlation coefficient"),
                Number.Double,
                d.rho_min,
                minValue=0.0,
                maxValue=1.0,
            ),
            Number(
                self.MAX_ELLIPSE,
                translate("Pushbroom", "Region growing: largest semi-major axis of the error ellipse (px)"),
                Number.Double,
                d.max_ellipse,
                minValue=0.0,
            ),
            Number(
                self.MAX_SHIFT,
                translate("Pushbroom", "Region growing: largest shift from the initial values (px)"),
                Number.Double,
                d.max_shift,
                minValue=0.0,
            ),
            Number(
                self.MAX_ITERATIONS,
                translate("Pushbroom", "Region growing: largest number of LSM iterations"),
                Number.Integer,
                d.max_iterations,
                minValue=1,
            ),
            Number(
                self.TILE,
                translate("Pushbroom", "Region growing: tile size of the reference image (px)"),
                Number.Integer,
                d.tile,
                minValue=16,
            ),
            Number(
                self.SIGMA_FACTOR,
                translate("Pushbroom", "Region growing: group 3 consistency test, k robust sigma"),
                Number.Double,
                m.sigma_factor,
                minValue=0.1,
            ),
            QgsProcessingParameterBoolean(
                self.GROW_SECOND,
                translate("Pushbroom", "Region growing: grow combination (b) where (a) found no points"),
                m.grow_second,
            ),
            QgsProcessingParameterBoolean(
                self.MPGC_REFINE,
                translate("Pushbroom", "Region growing: refine the group 3 points by MPGC"),
                m.mpgc,
            ),
            QgsProcessingParameterBoolean(
                self.MPGC_SUPPORT,
                translate("Pushbroom", "Region growing: MPGC with support weights (for DEMs)"),
                d.support_weights,
            ),
        ]
        return main, advanced

    def coarse_to_fine_parameters(self):
        """The coarse-to-fine strategy's parameters (CoarseToFineParams)."""
        c = CoarseToFineParams()
        return [
            Number(
                self.COARSE_TO_FINE_GRID,
                translate("Pushbroom", "Coarse-to-fine: grid point spacing at full resolution (px)"),
                Number.Integer,
                c.grid,
                minValue=2,
            ),
            Number(
                self.COARSE_TO_FINE_RHO_MIN,
                translate("Pushbroom", "Coarse-to-fine: minimum correlation coefficient at full resolution"),
                Number.Double,
                c.rho_min,
                minValue=0.0,
                maxValue=1.0,
            ),
            Number(
                self.COARSE_TO_FINE_TILE,
                translate("Pushbroom", "Coarse-to-fine: tile size of the reference image (px)"),
                Number.Integer,
                c.tile,
                minValue=16,
            ),
            QgsProcessingParameterBoolean(
                self.COARSE_TO_FINE_EDGE_POINTS,
                translate("Pushbroom", "Coarse-to-fine: matched edges as extra points and breaklines"),
                c.edge_points,
            ),
        ]

    def dense_parameters(self):
        """The dense strategy's parameters (DenseParams; its LSM template is TEMPLATE)."""
        e = DenseParams()
        return [
            Number(
                self.DENSE_TILE,
                translate("Pushbroom", "Dense: tile size of the reference image (px)"),
                Number.Integer,
                e.tile,
                minValue=64,
                maxValue=4096,
            ),
            Number(
                self.DENSE_STEP,
                translate("Pushbroom", "Dense: a point every ... px of the reference image"),
                Number.Integer,
                e.step,
                minValue=1,
            ),
            QgsProcessingParameterBoolean(
                self.DENSE_REFINE,
                translate("Pushbroom", "Dense: refine the positions by LSM in the original images (TEMPLATE px)"),
                e.lsm,
            ),
            Number(
                self.DENSE_WIDE_TEMPLATE,
                translate("Pushbroom", "Dense: a wider LSM template where TEMPLATE fails (px, odd; 0: off)"),
                Number.Integer,
                e.wide_template,
                minValue=0,
            ),
            QgsProcessingParameterBoolean(
                self.DENSE_MPGC,
                translate(
                    "Pushbroom", "Dense: refine a triplet's three-ray points by MPGC (matching about 2.5x slower)"
                ),
                e.mpgc,
            ),
            Number(
                self.DENSE_P1,
                translate("Pushbroom", "Dense: SGM penalty P1 (a disparity change of 1 px)"),
                Number.Double,
                e.sgm.p1,
                minValue=0.0,
            ),
            Number(
                self.DENSE_P2,
                translate("Pushbroom", "Dense: SGM penalty P2 (a larger change)"),
                Number.Double,
                e.sgm.p2,
                minValue=0.0,
            ),
        ]

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
            wide_template=self.DENSE_WIDE_TEMPLATE,
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
        load_styled(context, result.layer, translate("Pushbroom", "Mass points"), self.POINTS, "points_by_group.qml")
        return out
