"""pushbroom:importpoints and pushbroom:exportpoints — the Processing faces of
steps.point_files.import_points and export_points: control/check points and their image
measurements between a CSV file and the block."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputFile,
    QgsProcessingOutputNumber,
    QgsProcessingOutputVectorLayer,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterString,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.adjustment.control_points import ROLES
from ...algorithms.block import Block
from ...algorithms.steps.point_files import ImportParams, export_points, import_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, heights_choice, heights_parameter, replace_fewer_parameter, translate, translated

Number = QgsProcessingParameterNumber
#: labels of the point roles (control_points.ROLES)
ROLE_LABELS = {
    "control": QT_TRANSLATE_NOOP("Pushbroom", "Control point"),
    "check": QT_TRANSLATE_NOOP("Pushbroom", "Check point"),
}
#: labels of the import modes (Block.IMPORT_MODES)
MODE_LABELS = {
    "replace": QT_TRANSLATE_NOOP("Pushbroom", "Replace the block's points"),
    "merge": QT_TRANSLATE_NOOP("Pushbroom", "Merge: update points with the same id, add the others"),
}


class ImportPoints(PushbroomAlgorithm):
    NAME = "importpoints"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Import control and check points (CSV)")
    GROUP_ID = "block"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    INPUT = "INPUT"
    CRS = "CRS"
    HEIGHTS = "HEIGHTS"
    ROLE = "ROLE"
    CHECK_IDS = "CHECK_IDS"
    MODE = "MODE"
    SIGMA_E = "SIGMA_E"
    SIGMA_N = "SIGMA_N"
    SIGMA_H = "SIGMA_H"
    SIGMA_IMAGE = "SIGMA_IMAGE"
    MEAS_SUFFIX = "MEAS_SUFFIX"
    KEEP_IMPLAUSIBLE = "KEEP_IMPLAUSIBLE"
    REPLACE_FEWER = "REPLACE_FEWER"
    POINTS = "POINTS"
    CONTROL = "CONTROL"
    CHECK = "CHECK"
    MEASUREMENTS = "MEASUREMENTS"

    def initAlgorithm(self, config=None):
        d = ImportParams()
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterFile(
                self.INPUT,
                translate("Pushbroom", "Point file (CSV)"),
                fileFilter=translate("Pushbroom", "CSV files (*.csv *.txt);;All files (*.*)"),
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS,
                translate("Pushbroom", "CRS of x/y columns (lon/lat columns are WGS 84)"),
                "EPSG:4326",
                optional=True,
            )
        )
        self.addParameter(heights_parameter(self.HEIGHTS, translate("Pushbroom", "Heights")))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.ROLE,
                translate("Pushbroom", "Role of points without one in the file"),
                [translated(ROLE_LABELS[r]) for r in ROLES],
                defaultValue=ROLES.index(d.default_role),
            )
        )
        self.addParameter(
            QgsProcessingParameterString(
                self.CHECK_IDS, translate("Pushbroom", "Check point ids (comma-separated)"), d.check_ids, optional=True
            )
        )
        modes = Block.IMPORT_MODES
        self.addParameter(
            QgsProcessingParameterEnum(
                self.MODE,
                translate("Pushbroom", "Import mode"),
                [translated(MODE_LABELS[m]) for m in modes],
                defaultValue=modes.index(d.mode),
            )
        )
        self.addAdvancedParameters(
            [
                Number(
                    self.SIGMA_E,
                    translate("Pushbroom", "Default sigma east (m)"),
                    Number.Double,
                    d.sigma_e,
                    minValue=1e-6,
                ),
                Number(
                    self.SIGMA_N,
                    translate("Pushbroom", "Default sigma north (m)"),
                    Number.Double,
                    d.sigma_n,
                    minValue=1e-6,
                ),
                Number(
                    self.SIGMA_H,
                    translate("Pushbroom", "Default sigma height (m)"),
                    Number.Double,
                    d.sigma_h,
                    minValue=1e-6,
                ),
                Number(
                    self.SIGMA_IMAGE,
                    translate("Pushbroom", "Default sigma of the image measurements (px)"),
                    Number.Double,
                    d.image_sigma,
                    minValue=1e-6,
                ),
                QgsProcessingParameterString(
                    self.MEAS_SUFFIX,
                    translate("Pushbroom", "Measurement column suffix ('_meas' for the simulator's points.csv)"),
                    d.suffix,
                    optional=True,
                ),
                QgsProcessingParameterBoolean(
                    self.KEEP_IMPLAUSIBLE,
                    translate("Pushbroom", "Keep points the block's images and measurements disagree with (a warning)"),
                    d.keep_implausible,
                ),
                replace_fewer_parameter(self, translate("Pushbroom", "points and measurements")),
            ]
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(
                self.POINTS, translate("Pushbroom", "Control and check points"), QgsProcessing.TypeVectorPoint
            )
        )
        for name, text in [
            (self.CONTROL, QT_TRANSLATE_NOOP("Pushbroom", "Control points")),
            (self.CHECK, QT_TRANSLATE_NOOP("Pushbroom", "Check points")),
            (self.MEASUREMENTS, QT_TRANSLATE_NOOP("Pushbroom", "Image measurements")),
        ]:
            self.addOutput(QgsProcessingOutputNumber(name, translated(text)))
        self.addOutput(
            QgsProcessingOutputFile(
                self.BLOCK, translate("Pushbroom", "Block (updated; chains the next step in a model)")
            )
        )

    def import_params(self, parameters, context):
        """ImportParams of the parameters."""
        return ImportParams(
            mode=Block.IMPORT_MODES[self.parameterAsEnum(parameters, self.MODE, context)],
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            heights=heights_choice(self, parameters, self.HEIGHTS, context),
            default_role=ROLES[self.parameterAsEnum(parameters, self.ROLE, context)],
            **self.parameterValues(
                parameters,
                context,
                check_ids=self.CHECK_IDS,
                sigma_e=self.SIGMA_E,
                sigma_n=self.SIGMA_N,
                sigma_h=self.SIGMA_H,
                image_sigma=self.SIGMA_IMAGE,
                suffix=self.MEAS_SUFFIX,
                keep_implausible=self.KEEP_IMPLAUSIBLE,
                replace_fewer=self.REPLACE_FEWER,
            ),
        )

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = self.import_params(parameters, context)
        result = import_points(path, self.parameterAsFile(parameters, self.INPUT, context), params, feedback)
        load_styled(context, result.layer, "Control and check points", self.POINTS, "control_points.qml")
        return {
            self.BLOCK: path,
            self.POINTS: result.layer,
            self.CONTROL: result.control,
            self.CHECK: result.check,
            self.MEASUREMENTS: result.measurements,
        }


class ExportPoints(PushbroomAlgorithm):
    NAME = "exportpoints"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Export control and check points (CSV)")
    GROUP_ID = "block"

    # parameter and output keys: the names Processing, models and qgis_process use
    BLOCK = "BLOCK"
    OUTPUT = "OUTPUT"

    def initAlgorithm(self, config=None):
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, translate("Pushbroom", "Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.OUTPUT, translate("Pushbroom", "Point file"), translate("Pushbroom", "CSV files (*.csv)")
            )
        )

    def execute(self, parameters, context, feedback):
        output = export_points(
            self.parameterAsFile(parameters, self.BLOCK, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT, context),
            feedback,
        )
        return {self.OUTPUT: output}
