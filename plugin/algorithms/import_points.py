"""pushbroom:importpoints and pushbroom:exportpoints — control/check points and their image
measurements between a CSV file (algorithms/adjustment/control_points.py) and the block (algorithms/block/)."""
from qgis.core import (QgsProcessing, QgsProcessingOutputFile, QgsProcessingOutputNumber,
                       QgsProcessingOutputVectorLayer, QgsProcessingParameterBoolean, QgsProcessingParameterCrs,
                       QgsProcessingParameterEnum,
                       QgsProcessingParameterFile, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterString)

from ...algorithms.adjustment import control_points as cp
from ...algorithms.block import Block
from ...algorithms.adjustment.observations import IMAGE_SIGMA
from ..styles import load_styled
from .base import PushbroomAlgorithm

Number = QgsProcessingParameterNumber
HEIGHTS = ("Ellipsoidal (WGS 84)", "Orthometric (EGM96 geoid; needs PROJ's us_nga_egm96_15.tif grid)")
MODES = ("Replace the block's points", "Merge: update points with the same id, add the others")


class ImportPoints(PushbroomAlgorithm):
    NAME = "importpoints"
    DISPLAY_NAME = "Import control and check points (CSV)"
    GROUP = "Block"
    GROUP_ID = "block"
    HELP = ("Imports control and check points and their image measurements from a CSV file into the block "
            "(point layer 'control_points', table 'image_measurements'). Columns (any case; comma, semicolon or "
            "tab separated): <b>id</b>; <b>role</b> (control or check; optional, empty = the default role); "
            "<b>lon</b>, <b>lat</b> (WGS 84 degrees) or <b>x</b>, <b>y</b> (easting/northing in the CRS "
            "parameter); <b>h</b> (m, ellipsoidal or EGM96 orthometric, see Heights); optional <b>sigma_e</b>, "
            "<b>sigma_n</b>, <b>sigma_h</b> (m; empty = the default sigmas); per block image "
            "<b>&lt;image&gt;_col</b>, <b>&lt;image&gt;_row</b> and optional <b>&lt;image&gt;_sigma</b> (px, GDAL "
            "convention: centre of the first pixel 0.5, 0.5), each followed by the measurement column suffix "
            "(empty by default; '_meas' for the simulator's points.csv). Empty image cells: not measured in "
            "that image. Other columns are ignored with a warning. 'Check point ids' makes the listed points "
            "check points whatever their role column says. Replace mode replaces the block's points; merge "
            "mode updates points with the same id (their measurements in the images the file gives) and adds "
            "new ones. Points that do not lie within 2 km of an image footprint (at the block's terrain height "
            "range), or whose measurements lie over 2 km from where their coordinates project, are named and "
            "refused (lon/lat swapped, degrees given as projected x/y, another CRS) unless kept on purpose. The "
            "import is one transaction: a bad file leaves the block as it was.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterFile("INPUT", "Point file (CSV)",
                                                     fileFilter="CSV files (*.csv *.txt);;All files (*.*)"))
        self.addParameter(QgsProcessingParameterCrs("CRS", "CRS of x/y columns (lon/lat columns are WGS 84)",
                                                    "EPSG:4326", optional=True))
        self.addParameter(QgsProcessingParameterEnum("HEIGHTS", "Heights", list(HEIGHTS), defaultValue=0))
        self.addParameter(QgsProcessingParameterEnum("ROLE", "Role of points without one in the file",
                                                     list(cp.ROLES), defaultValue=0))
        self.addParameter(QgsProcessingParameterString("CHECK_IDS", "Check point ids (comma-separated)", "",
                                                       optional=True))
        self.addParameter(QgsProcessingParameterEnum("MODE", "Import mode", list(MODES), defaultValue=0))
        east, north, up = cp.DEFAULT_SIGMAS
        self.addAdvancedParameters([
            Number("SIGMA_E", "Default sigma east (m)", Number.Double, east, minValue=1e-6),
            Number("SIGMA_N", "Default sigma north (m)", Number.Double, north, minValue=1e-6),
            Number("SIGMA_H", "Default sigma height (m)", Number.Double, up, minValue=1e-6),
            Number("SIGMA_IMAGE", "Default sigma of the image measurements (px)", Number.Double,
                   IMAGE_SIGMA, minValue=1e-6),
            QgsProcessingParameterString("MEAS_SUFFIX", "Measurement column suffix ('_meas' for the simulator's "
                                         "points.csv)", "", optional=True),
            QgsProcessingParameterBoolean("KEEP_IMPLAUSIBLE", "Keep points that do not lie where the block's images "
                                          "are (with a warning)", False),
        ])
        self.addOutput(QgsProcessingOutputVectorLayer("POINTS", "Control and check points",
                                                      QgsProcessing.TypeVectorPoint))
        for name, text in [("CONTROL", "Control points"), ("CHECK", "Check points"),
                           ("MEASUREMENTS", "Image measurements")]:
            self.addOutput(QgsProcessingOutputNumber(name, text))
        self.addOutput(QgsProcessingOutputFile("BLOCK", "Block (updated; chains the next step in a model)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        stored = cp.import_csv(
            blk, self.parameterAsFile(parameters, "INPUT", context),
            mode=Block.IMPORT_MODES[self.parameterAsEnum(parameters, "MODE", context)], feedback=feedback,
            crs=self.parameterAsCrsDefinition(parameters, "CRS", context),
            heights=cp.HEIGHT_TYPES[self.parameterAsEnum(parameters, "HEIGHTS", context)],
            default_role=cp.ROLES[self.parameterAsEnum(parameters, "ROLE", context)],
            check_ids=[c.strip() for c in self.parameterAsString(parameters, "CHECK_IDS", context).split(",")],
            sigmas=tuple(self.parameterAsDouble(parameters, key, context) for key in ("SIGMA_E", "SIGMA_N", "SIGMA_H")),
            image_sigma=self.parameterAsDouble(parameters, "SIGMA_IMAGE", context),
            suffix=self.parameterAsString(parameters, "MEAS_SUFFIX", context),
            keep_implausible=self.parameterAsBool(parameters, "KEEP_IMPLAUSIBLE", context))
        feedback.pushInfo("points in the block: " + cp.summary(stored, blk.image_ids()))
        layer = blk.layer_source(Block.CONTROL_LAYER)
        load_styled(context, layer, "Control and check points", "POINTS", "control_points.qml")
        roles = stored.points["role"]
        return {"BLOCK": path, "POINTS": layer, "CONTROL": int((roles == "control").sum()),
                "CHECK": int((roles == "check").sum()), "MEASUREMENTS": len(stored.measurements)}


class ExportPoints(PushbroomAlgorithm):
    NAME = "exportpoints"
    DISPLAY_NAME = "Export control and check points (CSV)"
    GROUP = "Block"
    GROUP_ID = "block"
    HELP = ("Writes the block's control and check points and their image measurements to a CSV file in the "
            "format 'Import control and check points' reads (columns id, role, lon, lat, h, sigma_e, sigma_n, "
            "sigma_h, then <image>_col, <image>_row, <image>_sigma per block image; WGS 84 degrees, "
            "ellipsoidal heights, numbers at full precision), so an export imports back exactly.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block", extension="gpkg"))
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Point file", "CSV files (*.csv)"))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        output = self.parameterAsFileOutput(parameters, "OUTPUT", context)
        stored = cp.export_csv(blk, output)
        feedback.pushInfo(f"{output}: " + cp.summary(stored, blk.image_ids()))
        return {"OUTPUT": output}
