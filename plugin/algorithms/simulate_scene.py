"""pushbroom:simulatescene — a simulated SPOT block with exact truth (algorithms/simulation)."""
from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputFolder, QgsProcessingOutputMultipleLayers,
                       QgsProcessingOutputRasterLayer, QgsProcessingParameterBoolean,
                       QgsProcessingParameterEnum, QgsProcessingParameterFile,
                       QgsProcessingParameterFolderDestination, QgsProcessingParameterNumber,
                       QgsProcessingParameterRasterLayer)

from ...algorithms.simulation.scene import SceneConfig, simulate_scene
from .base import PushbroomAlgorithm

CONFIGURATIONS = [("spot5_triplet", "SPOT-5 along-track triplet (HRS1 +20 deg, HRG nadir, HRS2 -20 deg)"),
                  ("spot14_pair", "SPOT 1-4 across-track pair (two passes, B/H about 0.5)")]
BITS = [8, 12]
Number = QgsProcessingParameterNumber


class SimulateScene(PushbroomAlgorithm):
    NAME = "simulatescene"
    DISPLAY_NAME = "Simulate scene"
    GROUP = "Simulation"
    GROUP_ID = "simulation"
    HELP = ("Simulates a block of SPOT level-1A products over a real DEM (the Jacksboro fault DEM shipped "
            "with matplotlib) with exact truth: a sun-synchronous orbit with Earth rotation, attitude "
            "drift, per-detector look angles, forest and buildings on land-cover classes, sun shading, "
            "MTF, noise and quantisation; every pixel's ray is intersected with the DSM. Each image is "
            "written as IMAGERY.TIF + METADATA.DIM with the supplied orientation perturbed by known "
            "errors (about 30 m); truth/ holds the exact orientation and the injected corrections; "
            "dsm.tif, dtm.tif, classes.tif, orthoimage.tif and points.csv (control/check point "
            "candidates) are the ground truth. Same seed, same bytes.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        d = SceneConfig()
        self.addParameter(QgsProcessingParameterEnum("CONFIGURATION", "Configuration",
                                                     [label for _, label in CONFIGURATIONS], defaultValue=0))
        self.addParameter(Number("SIZE_KM", "Scene size (km)", Number.Double, d.size_km, minValue=1.0, maxValue=25.0))
        self.addParameter(Number("SEED", "Random seed", Number.Integer, d.seed, minValue=0))
        self.addParameter(QgsProcessingParameterEnum("BITS", "Radiometric resolution (bits)",
                                                     [str(b) for b in BITS], defaultValue=BITS.index(d.bits)))
        self.addParameter(Number("POINTS", "Control/check point candidates", Number.Integer, d.points, minValue=0))
        self.addParameter(Number("BLUNDERS", "Blunders among the point measurements", Number.Integer, d.blunders,
                                 minValue=0))
        advanced = [
            Number("NOISE", "Image noise sigma (DN at 8 bit)", Number.Double, d.noise, minValue=0.0),
            Number("FRACTAL", "Fractal terrain detail (x 4 m, 0 = off)", Number.Double, d.fractal, minValue=0.0),
            QgsProcessingParameterBoolean("SURFACE_OBJECTS", "Forest and buildings in the DSM", d.surface_objects),
            Number("MEASUREMENT_SIGMA", "Point measurement noise (px)", Number.Double, d.measurement_sigma,
                   minValue=0.0),
            QgsProcessingParameterBoolean("MARKERS", "Paint bright markers at the point candidates", d.markers),
            Number("ERROR_SCALE", "Scale of the injected orientation errors (0: supplied = truth)", Number.Double,
                   d.error_scale, minValue=0.0),
            Number("GRID_M", "Ground grid cell (m)", Number.Double, d.grid_m, minValue=1.0, maxValue=20.0),
            QgsProcessingParameterFile("LOOK_TABLE", "Look angles and line period from this METADATA.DIM",
                                       extension="DIM", optional=True),
            QgsProcessingParameterRasterLayer("ORTHOIMAGE", "Ground reflectance from this orthoimage", optional=True),
        ]
        self.addAdvancedParameters(advanced)
        self.addParameter(QgsProcessingParameterFolderDestination("OUTPUT", "Output folder"))
        self.addOutput(QgsProcessingOutputMultipleLayers("IMAGES", "Images (IMAGERY.TIF)"))
        for key, label in [("DSM", "True DSM"), ("DTM", "True DTM"), ("CLASSES", "Land-cover classes"),
                           ("ORTHOIMAGE", "True orthoimage")]:
            self.addOutput(QgsProcessingOutputRasterLayer(key, label))
        self.addOutput(QgsProcessingOutputFile("POINTS", "Control/check point candidates (CSV)"))
        self.addOutput(QgsProcessingOutputFile("TRUTH", "Truth file (JSON)"))
        self.addOutput(QgsProcessingOutputFolder("FOLDER", "Scene folder"))

    def execute(self, parameters, context, feedback):
        def number(key):
            return self.parameterAsDouble(parameters, key, context)

        def integer(key):
            return self.parameterAsInt(parameters, key, context)

        def flag(key):
            return self.parameterAsBool(parameters, key, context)

        ortho = self.parameterAsRasterLayer(parameters, "ORTHOIMAGE", context)
        config = SceneConfig(
            configuration=CONFIGURATIONS[self.parameterAsEnum(parameters, "CONFIGURATION", context)][0],
            size_km=number("SIZE_KM"), seed=integer("SEED"),
            bits=BITS[self.parameterAsEnum(parameters, "BITS", context)],
            points=integer("POINTS"), blunders=integer("BLUNDERS"), noise=number("NOISE"),
            fractal=number("FRACTAL"), surface_objects=flag("SURFACE_OBJECTS"),
            measurement_sigma=number("MEASUREMENT_SIGMA"), markers=flag("MARKERS"),
            error_scale=number("ERROR_SCALE"), grid_m=number("GRID_M"),
            look_table=self.parameterAsFile(parameters, "LOOK_TABLE", context) or "",
            orthoimage=ortho.source() if ortho is not None else "")
        out = self.parameterAsString(parameters, "OUTPUT", context)
        paths = simulate_scene(config, out, feedback=feedback)
        images = [paths["images"][name]["imagery"] for name in paths["images"]]
        feedback.pushInfo(f"simulated {len(images)} images into {paths['folder']}: " + ", ".join(paths["images"]))
        return {"OUTPUT": paths["folder"], "FOLDER": paths["folder"], "IMAGES": images, "DSM": paths["dsm"],
                "DTM": paths["dtm"], "CLASSES": paths["classes"], "ORTHOIMAGE": paths["orthoimage"],
                "POINTS": paths["points"], "TRUTH": paths["truth"]}
