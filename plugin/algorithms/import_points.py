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

from ...algorithms.adjustment.control_points import ROLES
from ...algorithms.block import Block
from ...algorithms.steps.point_files import ImportParams, export_points, import_points
from ..styles import load_styled
from .base import PushbroomAlgorithm, heights_choice, heights_parameter, replace_fewer_parameter

Number = QgsProcessingParameterNumber
#: labels of the import modes (Block.IMPORT_MODES)
MODE_LABELS = {
    "replace": "Replace the block's points",
    "merge": "Merge: update points with the same id, add the others",
}


class ImportPoints(PushbroomAlgorithm):
    NAME = "importpoints"
    DISPLAY_NAME = "Import control and check points (CSV)"
    GROUP_ID = "block"

    KEYS = (
        "BLOCK INPUT CRS HEIGHTS ROLE CHECK_IDS MODE SIGMA_E SIGMA_N SIGMA_H SIGMA_IMAGE MEAS_SUFFIX "
        "KEEP_IMPLAUSIBLE REPLACE_FEWER POINTS CONTROL CHECK MEASUREMENTS"
    )

    def initAlgorithm(self, config=None):
        d, tr = ImportParams(), self.tr
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, tr("Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterFile(
                self.INPUT, tr("Point file (CSV)"), fileFilter=tr("CSV files (*.csv *.txt);;All files (*.*)")
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, tr("CRS of x/y columns (lon/lat columns are WGS 84)"), "EPSG:4326", optional=True
            )
        )
        self.addParameter(heights_parameter(self.HEIGHTS, tr("Heights")))
        self.addParameter(
            QgsProcessingParameterEnum(
                self.ROLE,
                tr("Role of points without one in the file"),
                list(ROLES),
                defaultValue=ROLES.index(d.default_role),
            )
        )
        self.addParameter(
            QgsProcessingParameterString(
                self.CHECK_IDS, tr("Check point ids (comma-separated)"), d.check_ids, optional=True
            )
        )
        modes = Block.IMPORT_MODES
        self.addParameter(
            QgsProcessingParameterEnum(
                self.MODE, tr("Import mode"), [tr(MODE_LABELS[m]) for m in modes], defaultValue=modes.index(d.mode)
            )
        )
        self.addAdvancedParameters(
            [
                Number(self.SIGMA_E, tr("Default sigma east (m)"), Number.Double, d.sigma_e, minValue=1e-6),
                Number(self.SIGMA_N, tr("Default sigma north (m)"), Number.Double, d.sigma_n, minValue=1e-6),
                Number(self.SIGMA_H, tr("Default sigma height (m)"), Number.Double, d.sigma_h, minValue=1e-6),
                Number(
                    self.SIGMA_IMAGE,
                    tr("Default sigma of the image measurements (px)"),
                    Number.Double,
                    d.image_sigma,
                    minValue=1e-6,
                ),
                QgsProcessingParameterString(
                    self.MEAS_SUFFIX,
                    tr("Measurement column suffix ('_meas' for the simulator's points.csv)"),
                    d.suffix,
                    optional=True,
                ),
                QgsProcessingParameterBoolean(
                    self.KEEP_IMPLAUSIBLE,
                    tr(
                        "Keep points that do not lie where the block's "
                        "images and their measurements say (with a warning)"
                    ),
                    d.keep_implausible,
                ),
                replace_fewer_parameter(self, tr("points and measurements")),
            ]
        )
        self.addOutput(
            QgsProcessingOutputVectorLayer(self.POINTS, tr("Control and check points"), QgsProcessing.TypeVectorPoint)
        )
        for name, text in [
            (self.CONTROL, "Control points"),
            (self.CHECK, "Check points"),
            (self.MEASUREMENTS, "Image measurements"),
        ]:
            self.addOutput(QgsProcessingOutputNumber(name, tr(text)))
        self.addOutput(QgsProcessingOutputFile(self.BLOCK, tr("Block (updated; chains the next step in a model)")))

    def execute(self, parameters, context, feedback):
        path = self.parameterAsFile(parameters, self.BLOCK, context)
        params = ImportParams(
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
    DISPLAY_NAME = "Export control and check points (CSV)"
    GROUP_ID = "block"

    KEYS = "BLOCK OUTPUT"

    def initAlgorithm(self, config=None):
        self.addParameter(QgsProcessingParameterFile(self.BLOCK, self.tr("Block"), extension="gpkg"))
        self.addParameter(
            QgsProcessingParameterFileDestination(self.OUTPUT, self.tr("Point file"), self.tr("CSV files (*.csv)"))
        )

    def execute(self, parameters, context, feedback):
        output = export_points(
            self.parameterAsFile(parameters, self.BLOCK, context),
            self.parameterAsFileOutput(parameters, self.OUTPUT, context),
            feedback,
        )
        return {self.OUTPUT: output}
