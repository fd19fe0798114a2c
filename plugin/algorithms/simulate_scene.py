"""pushbroom:simulatescene — the Processing face of simulation.scene.simulate_scene: a simulated SPOT
block with exact truth."""

from qgis.core import (
    QgsProcessingOutputFile,
    QgsProcessingOutputFolder,
    QgsProcessingOutputMultipleLayers,
    QgsProcessingOutputRasterLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterLayer,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.simulation import scene
from ...algorithms.simulation.instruments import CONFIGURATIONS
from ...algorithms.simulation.scene import SIZE_KM, SceneConfig, simulate_scene
from .base import PushbroomAlgorithm, cog_parameter, translate, translated

#: labels of the configurations (instruments.CONFIGURATIONS)
CONFIGURATION_LABELS = {
    "spot5_triplet": QT_TRANSLATE_NOOP(
        "Pushbroom", "SPOT-5 along-track triplet (HRS1 +20 deg, HRG nadir, HRS2 -20 deg)"
    ),
    "spot14_pair": QT_TRANSLATE_NOOP("Pushbroom", "SPOT 1-4 across-track pair (two passes, B/H about 0.5)"),
}
Number = QgsProcessingParameterNumber


class SimulateScene(PushbroomAlgorithm):
    NAME = "simulatescene"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Simulate scene")
    GROUP_ID = "simulation"

    WHOLE_FOLDERS = {"OUTPUT": scene.TRUTH}  # the scene folder is replaced as a whole (simulate_scene)
    # parameter and output keys: the names Processing, models and qgis_process use
    CONFIGURATION = "CONFIGURATION"
    SIZE_KM = "SIZE_KM"
    SEED = "SEED"
    BITS = "BITS"
    POINTS = "POINTS"
    BLUNDERS = "BLUNDERS"
    NOISE = "NOISE"
    FRACTAL = "FRACTAL"
    SURFACE_OBJECTS = "SURFACE_OBJECTS"
    MEASUREMENT_SIGMA = "MEASUREMENT_SIGMA"
    MARKERS = "MARKERS"
    ERROR_SCALE = "ERROR_SCALE"
    GRID_M = "GRID_M"
    LOOK_TABLE = "LOOK_TABLE"
    ORTHOIMAGE = "ORTHOIMAGE"
    COG = "COG"
    OUTPUT = "OUTPUT"
    IMAGES = "IMAGES"
    DSM = "DSM"
    DTM = "DTM"
    CLASSES = "CLASSES"
    TRUTH = "TRUTH"
    FOLDER = "FOLDER"

    def initAlgorithm(self, config=None):
        d = SceneConfig()
        self.addParameter(
            QgsProcessingParameterEnum(
                self.CONFIGURATION,
                translate("Pushbroom", "Configuration"),
                [translated(CONFIGURATION_LABELS[c]) for c in CONFIGURATIONS],
                defaultValue=CONFIGURATIONS.index(d.configuration),
            )
        )
        self.addParameter(
            Number(
                self.SIZE_KM,
                translate("Pushbroom", "Scene size (km)"),
                Number.Double,
                d.size_km,
                minValue=SIZE_KM[0],
                maxValue=SIZE_KM[1],
            )
        )
        self.addParameter(Number(self.SEED, translate("Pushbroom", "Random seed"), Number.Integer, d.seed, minValue=0))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.BITS,
                translate("Pushbroom", "Radiometric resolution (bits)"),
                [str(b) for b in scene.BITS],
                defaultValue=scene.BITS.index(d.bits),
            )
        )
        self.addParameter(
            Number(
                self.POINTS,
                translate("Pushbroom", "Control/check point candidates"),
                Number.Integer,
                d.points,
                minValue=0,
            )
        )
        self.addParameter(
            Number(
                self.BLUNDERS,
                translate("Pushbroom", "Blunders among the point measurements"),
                Number.Integer,
                d.blunders,
                minValue=0,
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.NOISE,
                    translate("Pushbroom", "Image noise sigma (DN at 8 bit)"),
                    Number.Double,
                    d.noise,
                    minValue=0.0,
                ),
                Number(
                    self.FRACTAL,
                    translate("Pushbroom", "Fractal terrain detail (x 4 m, 0 = off)"),
                    Number.Double,
                    d.fractal,
                    minValue=0.0,
                ),
                QgsProcessingParameterBoolean(
                    self.SURFACE_OBJECTS, translate("Pushbroom", "Forest and buildings in the DSM"), d.surface_objects
                ),
                Number(
                    self.MEASUREMENT_SIGMA,
                    translate("Pushbroom", "Point measurement noise (px)"),
                    Number.Double,
                    d.measurement_sigma,
                    minValue=0.0,
                ),
                QgsProcessingParameterBoolean(
                    self.MARKERS, translate("Pushbroom", "Paint bright markers at the point candidates"), d.markers
                ),
                Number(
                    self.ERROR_SCALE,
                    translate("Pushbroom", "Scale of the injected orientation errors (0: supplied = truth)"),
                    Number.Double,
                    d.error_scale,
                    minValue=0.0,
                ),
                Number(
                    self.GRID_M,
                    translate("Pushbroom", "Ground grid cell (m)"),
                    Number.Double,
                    d.grid_m,
                    minValue=1.0,
                    maxValue=20.0,
                ),
                QgsProcessingParameterFile(
                    self.LOOK_TABLE,
                    translate("Pushbroom", "Look angles and line period from this METADATA.DIM"),
                    extension="DIM",
                    optional=True,
                ),
                QgsProcessingParameterRasterLayer(
                    self.ORTHOIMAGE, translate("Pushbroom", "Ground reflectance from this orthoimage"), optional=True
                ),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(QgsProcessingParameterFolderDestination(self.OUTPUT, translate("Pushbroom", "Output folder")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.IMAGES, translate("Pushbroom", "Images (IMAGERY.TIF)")))
        for key, label in [
            (self.DSM, QT_TRANSLATE_NOOP("Pushbroom", "True DSM")),
            (self.DTM, QT_TRANSLATE_NOOP("Pushbroom", "True DTM")),
            (self.CLASSES, QT_TRANSLATE_NOOP("Pushbroom", "Land-cover classes")),
            (self.ORTHOIMAGE, QT_TRANSLATE_NOOP("Pushbroom", "True orthoimage")),
        ]:
            self.addOutput(QgsProcessingOutputRasterLayer(key, translated(label)))
        self.addOutput(
            QgsProcessingOutputFile(self.POINTS, translate("Pushbroom", "Control/check point candidates (CSV)"))
        )
        self.addOutput(QgsProcessingOutputFile(self.TRUTH, translate("Pushbroom", "Truth file (JSON)")))
        self.addOutput(QgsProcessingOutputFolder(self.FOLDER, translate("Pushbroom", "Scene folder")))

    def scene_config(self, parameters, context):
        """SceneConfig of the parameters."""
        ortho = self.parameterAsRasterLayer(parameters, self.ORTHOIMAGE, context)
        return SceneConfig(
            configuration=CONFIGURATIONS[self.parameterAsEnum(parameters, self.CONFIGURATION, context)],
            bits=scene.BITS[self.parameterAsEnum(parameters, self.BITS, context)],
            look_table=self.parameterAsFile(parameters, self.LOOK_TABLE, context) or "",
            orthoimage=ortho.source() if ortho is not None else "",
            **self.parameterValues(
                parameters,
                context,
                size_km=self.SIZE_KM,
                seed=self.SEED,
                points=self.POINTS,
                blunders=self.BLUNDERS,
                noise=self.NOISE,
                fractal=self.FRACTAL,
                surface_objects=self.SURFACE_OBJECTS,
                measurement_sigma=self.MEASUREMENT_SIGMA,
                markers=self.MARKERS,
                error_scale=self.ERROR_SCALE,
                grid_m=self.GRID_M,
            ),
        )

    def execute(self, parameters, context, feedback):
        config = self.scene_config(parameters, context)
        paths = simulate_scene(
            config,
            self.parameterAsString(parameters, self.OUTPUT, context),
            feedback=feedback,
            cog=self.parameterAsBool(parameters, self.COG, context),
        )
        images = [paths["images"][name]["imagery"] for name in paths["images"]]
        feedback.pushInfo(f"simulated {len(images)} images into {paths['folder']}: " + ", ".join(paths["images"]))
        return {
            self.OUTPUT: paths["folder"],
            self.FOLDER: paths["folder"],
            self.IMAGES: images,
            self.DSM: paths["dsm"],
            self.DTM: paths["dtm"],
            self.CLASSES: paths["classes"],
            self.ORTHOIMAGE: paths["orthoimage"],
            self.POINTS: paths["points"],
            self.TRUTH: paths["truth"],
        }
