"""pushbroom:assessaccuracy — the Processing face of quality.assess_accuracy.assess_accuracy: height
differences of a point cloud and/or a DEM against a reference DTM/DSM, with statistics, figures and an
HTML report."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterField,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterVectorLayer,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms.errors import InputError
from ...algorithms.quality.assess_accuracy import AssessParams, assess_accuracy
from ...algorithms.quality.classes import PolygonClasses
from ..styles import style_on_completion
from .base import (
    PushbroomAlgorithm,
    cog_parameter,
    execution_choice,
    execution_parameters,
    heights_choice,
    heights_parameter,
    translate,
)
from .dem_nodata import nodata_parameter


class AssessAccuracy(PushbroomAlgorithm):
    NAME = "assessaccuracy"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Assess accuracy (dh against a reference DEM)")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    REFERENCE = "REFERENCE"
    REFERENCE_HEIGHTS = "REFERENCE_HEIGHTS"
    POINTS = "POINTS"
    DEM = "DEM"
    DEM_HEIGHTS = "DEM_HEIGHTS"
    CLASS_RASTER = "CLASS_RASTER"
    CLASS_POLYGONS = "CLASS_POLYGONS"
    CLASS_FIELD = "CLASS_FIELD"
    SLOPE_THRESHOLD = "SLOPE_THRESHOLD"
    POINTS_HEIGHTS = "POINTS_HEIGHTS"
    REFERENCE_NODATA = "REFERENCE_NODATA"
    COREGISTER = "COREGISTER"
    COREGISTER_TILT = "COREGISTER_TILT"
    COREGISTER_MASK = "COREGISTER_MASK"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    COG = "COG"
    REPORT = "REPORT"
    DH = "DH"
    TABLE = "TABLE"

    def initAlgorithm(self, config=None):
        d = AssessParams()
        self.addParameter(
            QgsProcessingParameterRasterLayer(self.REFERENCE, translate("Pushbroom", "Reference DTM/DSM"))
        )
        self.addParameter(heights_parameter(self.REFERENCE_HEIGHTS, translate("Pushbroom", "Reference heights")))
        self.addParameter(
            QgsProcessingParameterFile(
                self.POINTS,
                translate("Pushbroom", "Point cloud (object points)"),
                optional=True,
                fileFilter=translate("Pushbroom", "Point clouds (*.las *.laz *.gpkg);;All files (*.*)"),
            )
        )
        self.addParameter(QgsProcessingParameterRasterLayer(self.DEM, translate("Pushbroom", "DEM"), optional=True))
        self.addParameter(heights_parameter(self.DEM_HEIGHTS, translate("Pushbroom", "DEM heights")))
        self.addParameter(
            QgsProcessingParameterRasterLayer(self.CLASS_RASTER, translate("Pushbroom", "Class raster"), optional=True)
        )
        self.addParameter(
            QgsProcessingParameterVectorLayer(
                self.CLASS_POLYGONS,
                translate("Pushbroom", "Class polygons"),
                optional=True,
                types=[QgsProcessing.TypeVectorPolygon],
            )
        )
        self.addParameter(
            QgsProcessingParameterField(
                self.CLASS_FIELD,
                translate("Pushbroom", "Class field of the polygons"),
                optional=True,
                parentLayerParameterName=self.CLASS_POLYGONS,
            )
        )
        self.addParameter(
            QgsProcessingParameterNumber(
                self.SLOPE_THRESHOLD,
                translate("Pushbroom", "Slope of mountainous terrain (degrees, of the reference)"),
                QgsProcessingParameterNumber.Double,
                d.slope_threshold,
                minValue=0.01,
                maxValue=89.9,
            )
        )
        self.addParameter(
            QgsProcessingParameterBoolean(
                self.COREGISTER,
                translate("Pushbroom", "Assess the DEM co-registered to the reference too (before and after)"),
                d.coregister,
                optional=True,  # the models saved before it still validate
            )
        )
        self.addAdvancedParameters(
            [
                heights_parameter(self.POINTS_HEIGHTS, translate("Pushbroom", "Point cloud heights")),
                nodata_parameter(self.REFERENCE_NODATA, translate("Pushbroom", "reference DTM/DSM")),
                QgsProcessingParameterBoolean(
                    self.COREGISTER_TILT,
                    translate("Pushbroom", "Co-register with a tilt (a plane) too"),
                    d.coregister_tilt,
                    optional=True,
                ),
                QgsProcessingParameterRasterLayer(
                    self.COREGISTER_MASK,
                    translate("Pushbroom", "Unstable terrain left out of the co-registration (non-zero cells)"),
                    optional=True,
                ),
                *execution_parameters(self, d.execution.workers, optional=True),
            ]
        )
        self.addParameter(cog_parameter(self))
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.REPORT, translate("Pushbroom", "Report"), translate("Pushbroom", "HTML files (*.html)")
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.DH, translate("Pushbroom", "dh raster (DEM input)"), optional=True, createByDefault=False
            )
        )
        self.addParameter(
            QgsProcessingParameterFileDestination(
                self.TABLE,
                translate("Pushbroom", "Statistics table"),
                translate("Pushbroom", "CSV files (*.csv)"),
                optional=True,
                createByDefault=False,
            )
        )

    def _class_polygons(self, parameters, context):
        """(PolygonClasses, description) of the class polygons and their class field, or (None, "")."""
        polygons = self.parameterAsVectorLayer(parameters, self.CLASS_POLYGONS, context)
        if polygons is None:
            return None, ""
        fields = self.parameterAsFields(parameters, self.CLASS_FIELD, context)
        if not fields:
            raise InputError("name the class field of the class polygons")
        geometries, values = [], []
        for feature in polygons.getFeatures():
            if feature.hasGeometry():
                geometries.append(bytes(feature.geometry().asWkb()))
                values.append(feature[fields[0]])
        return PolygonClasses(geometries, values, polygons.crs().toWkt()), f"{polygons.source()} ({fields[0]})"

    def assess_params(self, parameters, context):
        """AssessParams of the parameters."""

        def source(key):
            layer = self.parameterAsRasterLayer(parameters, key, context)
            return layer.source() if layer is not None else None

        heights = {
            name: heights_choice(self, parameters, key, context)
            for name, key in [
                ("reference_heights", self.REFERENCE_HEIGHTS),
                ("points_heights", self.POINTS_HEIGHTS),
                ("dem_heights", self.DEM_HEIGHTS),
            ]
        }
        polygons, polygons_source = self._class_polygons(parameters, context)
        return AssessParams(
            reference=source(self.REFERENCE),
            dem=source(self.DEM),
            class_raster=source(self.CLASS_RASTER),
            coregister_mask=source(self.COREGISTER_MASK),
            points=self.parameterAsFile(parameters, self.POINTS, context) or None,
            class_polygons=polygons,
            class_polygons_source=polygons_source,
            report=self.parameterAsFileOutput(parameters, self.REPORT, context),
            table=self.parameterAsFileOutput(parameters, self.TABLE, context) or None,
            dh=self.parameterAsOutputLayer(parameters, self.DH, context) or None,
            **heights,
            execution=execution_choice(self, parameters, context),
            cog=self.parameterAsBool(parameters, self.COG, context),
            **self.parameterValues(
                parameters,
                context,
                slope_threshold=self.SLOPE_THRESHOLD,
                reference_nodata=self.REFERENCE_NODATA,
                coregister=self.COREGISTER,
                coregister_tilt=self.COREGISTER_TILT,
            ),
        )

    def execute(self, parameters, context, feedback):
        params = self.assess_params(parameters, context)
        result = assess_accuracy(params, feedback)
        out = {self.REPORT: result.report}
        if result.table:
            out[self.TABLE] = result.table
        if result.dh:
            out[self.DH] = result.dh
            style_on_completion(context, params.dh, "dh.qml")
        return out
