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

from ...algorithms.simulation import scene
from ...algorithms.simulation.instruments import CONFIGURATIONS
from ...algorithms.simulation.scene import SIZE_KM, SceneConfig, simulate_scene
from .base import PushbroomAlgorithm

#: labels of the configurations (instruments.CONFIGURATIONS)
CONFIGURATION_LABELS = {
    "spot5_triplet": "SPOT-5 along-track triplet (HRS1 +20 deg, HRG nadir, HRS2 -20 deg)",
    "spot14_pair": "SPOT 1-4 across-track pair (two passes, B/H about 0.5)",
}
Number = QgsProcessingParameterNumber


class SimulateScene(PushbroomAlgorithm):
    NAME = "simulatescene"
    DISPLAY_NAME = "Simulate scene"
    GROUP_ID = "simulation"

    WHOLE_FOLDERS = {"OUTPUT": scene.TRUTH}  # the scene folder is replaced as a whole (simulate_scene)
    KEYS = (
        "CONFIGURATION SIZE_KM SEED BITS POINTS BLUNDERS NOISE FRACTAL SURFACE_OBJECTS MEASUREMENT_SIGMA "
        "MARKERS ERROR_SCALE GRID_M LOOK_TABLE ORTHOIMAGE OUTPUT IMAGES DSM DTM CLASSES TRUTH FOLDER"
    )

    def initAlgorithm(self, config=None):
        d, tr = SceneConfig(), self.tr
        self.addParameter(
            QgsProcessingParameterEnum(
                self.CONFIGURATION,
                tr("Configuration"),
                [tr(CONFIGURATION_LABELS[c]) for c in CONFIGURATIONS],
                defaultValue=CONFIGURATIONS.index(d.configuration),
            )
        )
        self.addParameter(
            Number(
                self.SIZE_KM, tr("Scene size (km)"), Number.Double, d.size_km, minValue=SIZE_KM[0], maxValue=SIZE_KM[1]
            )
        )
        self.addParameter(Number(self.SEED, tr("Random seed"), Number.Integer, d.seed, minValue=0))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.BITS,
                tr("Radiometric resolution (bits)"),
                [str(b) for b in scene.BITS],
                defaultValue=scene.BITS.index(d.bits),
            )
        )
        self.addParameter(
            Number(self.POINTS, tr("Control/check point candidates"), Number.Integer, d.points, minValue=0)
        )
        self.addParameter(
            Number(self.BLUNDERS, tr("Blunders among the point measurements"), Number.Integer, d.blunders, minValue=0)
        )
        self.addAdvancedParameters(
            [
                Number(self.NOISE, tr("Image noise sigma (DN at 8 bit)"), Number.Double, d.noise, minValue=0.0),
                Number(
                    self.FRACTAL, tr("Fractal terrain detail (x 4 m, 0 = off)"), Number.Double, d.fractal, minValue=0.0
                ),
                QgsProcessingParameterBoolean(
                    self.SURFACE_OBJECTS, tr("Forest and buildings in the DSM"), d.surface_objects
                ),
                Number(
                    self.MEASUREMENT_SIGMA,
                    tr("Point measurement noise (px)"),
                    Number.Double,
                    d.measurement_sigma,
                    minValue=0.0,
                ),
                QgsProcessingParameterBoolean(
                    self.MARKERS, tr("Paint bright markers at the point candidates"), d.markers
                ),
                Number(
                    self.ERROR_SCALE,
                    tr("Scale of the injected orientation errors (0: supplied = truth)"),
                    Number.Double,
                    d.error_scale,
                    minValue=0.0,
                ),
                Number(self.GRID_M, tr("Ground grid cell (m)"), Number.Double, d.grid_m, minValue=1.0, maxValue=20.0),
                QgsProcessingParameterFile(
                    self.LOOK_TABLE,
                    tr("Look angles and line period from this METADATA.DIM"),
                    extension="DIM",
                    optional=True,
                ),
                QgsProcessingParameterRasterLayer(
                    self.ORTHOIMAGE, tr("Ground reflectance from this orthoimage"), optional=True
                ),
            ]
        )
        self.addParameter(QgsProcessingParameterFolderDestination(self.OUTPUT, tr("Output folder")))
        self.addOutput(QgsProcessingOutputMultipleLayers(self.IMAGES, tr("Images (IMAGERY.TIF)")))
        for key, label in [
            (self.DSM, "True DSM"),
            (self.DTM, "True DTM"),
            (self.CLASSES, "Land-cover classes"),
            (self.ORTHOIMAGE, "True orthoimage"),
        ]:
            self.addOutput(QgsProcessingOutputRasterLayer(key, tr(label)))
        self.addOutput(QgsProcessingOutputFile(self.POINTS, tr("Control/check point candidates (CSV)")))
        self.addOutput(QgsProcessingOutputFile(self.TRUTH, tr("Truth file (JSON)")))
        self.addOutput(QgsProcessingOutputFolder(self.FOLDER, tr("Scene folder")))

    def execute(self, parameters, context, feedback):
        ortho = self.parameterAsRasterLayer(parameters, self.ORTHOIMAGE, context)
        config = SceneConfig(
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
        paths = simulate_scene(config, self.parameterAsString(parameters, self.OUTPUT, context), feedback=feedback)
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
