"""pushbroom:assessaccuracy — height differences of a point cloud and/or a DEM against a reference
DTM/DSM with statistics per point group, class and slope, figures and one HTML report
(K 3.6-3.7, Z 4; algorithms/quality/)."""
from qgis.core import (QgsProcessing, QgsProcessingParameterEnum, QgsProcessingParameterField,
                       QgsProcessingParameterFile, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination,
                       QgsProcessingParameterRasterLayer, QgsProcessingParameterVectorLayer)

from ...algorithms import progress
from ...algorithms.adjustment.control_points import HEIGHT_TYPES
from ...algorithms.errors import InputError
from ...algorithms.quality.assessment import SLOPE_THRESHOLD, assess
from ...algorithms.quality.classes import ClassRaster, PolygonClasses
from ...algorithms.quality.height_differences import write_dh_raster
from ..styles import style_on_completion
from .base import PushbroomAlgorithm
from .dem_nodata import nodata_parameter
from .import_points import HEIGHTS


class AssessAccuracy(PushbroomAlgorithm):
    NAME = "assessaccuracy"
    DISPLAY_NAME = "Assess accuracy (dh against a reference DEM)"
    GROUP = "Surface"
    GROUP_ID = "surface"
    HELP = ("Height differences dh = assessed height - reference height of the object points of a point cloud "
            "(LAS/LAZ or GeoPackage from pushbroom:intersectpoints) and/or of the cells of a DEM against a "
            "reference DTM or DSM in any CRS (Kornus et al. 2006, 3.6-3.7; Zhang and Gruen 2004, 4). The "
            "reference is interpolated bilinearly at each point; for a DEM it is resampled onto the DEM's grid "
            "(the average of its cells where it is finer, bilinear otherwise). Heights are ellipsoidal or EGM96 "
            "orthometric per input. Statistics (N, min, mean, max, RMS, sigma, NMAD, 95 % quantile of |dh|, "
            "shares of |dh| < 2 m, 2-5 m, > 5 m) per point group, per class (a class raster such as the "
            "simulator's classes.tif, or polygons with a class field) and for flat/moderate vs mountainous "
            "terrain (slope of the reference against a threshold) go to the log, an HTML report with "
            "histograms and a colour-coded dh map, and optionally a CSV table; for a DEM an optional dh raster. "
            "Reference heights outside -500 .. 9000 m (voids not flagged as nodata) are reported, and a void value "
            "can be declared as the reference's nodata.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterRasterLayer("REFERENCE", "Reference DTM/DSM"))
        self.addParameter(QgsProcessingParameterEnum("REFERENCE_HEIGHTS", "Reference heights", HEIGHTS, defaultValue=0))
        self.addParameter(QgsProcessingParameterFile(
            "POINTS", "Point cloud (object points)", optional=True,
            fileFilter="Point clouds (*.las *.laz *.gpkg);;All files (*.*)"))
        self.addParameter(QgsProcessingParameterRasterLayer("DEM", "DEM", optional=True))
        self.addParameter(QgsProcessingParameterEnum("DEM_HEIGHTS", "DEM heights", HEIGHTS, defaultValue=0))
        self.addParameter(QgsProcessingParameterRasterLayer("CLASS_RASTER", "Class raster", optional=True))
        self.addParameter(QgsProcessingParameterVectorLayer("CLASS_POLYGONS", "Class polygons", optional=True,
                                                            types=[QgsProcessing.TypeVectorPolygon]))
        self.addParameter(QgsProcessingParameterField("CLASS_FIELD", "Class field of the polygons", optional=True,
                                                      parentLayerParameterName="CLASS_POLYGONS"))
        self.addParameter(QgsProcessingParameterNumber(
            "SLOPE_THRESHOLD", "Slope of mountainous terrain (degrees, of the reference)",
            QgsProcessingParameterNumber.Double, SLOPE_THRESHOLD, minValue=0.01, maxValue=89.9))
        self.addAdvancedParameters([
            QgsProcessingParameterEnum("POINTS_HEIGHTS", "Point cloud heights", HEIGHTS, defaultValue=0),
            nodata_parameter("REFERENCE_NODATA", "reference DTM/DSM")])
        self.addParameter(QgsProcessingParameterFileDestination("REPORT", "Report", "HTML files (*.html)"))
        self.addParameter(QgsProcessingParameterRasterDestination("DH", "dh raster (DEM input)", optional=True,
                                                                  createByDefault=False))
        self.addParameter(QgsProcessingParameterFileDestination("TABLE", "Statistics table", "CSV files (*.csv)",
                                                                optional=True, createByDefault=False))

    def _classes(self, parameters, context):
        raster = self.parameterAsRasterLayer(parameters, "CLASS_RASTER", context)
        polygons = self.parameterAsVectorLayer(parameters, "CLASS_POLYGONS", context)
        if raster is not None and polygons is not None:
            raise InputError("give a class raster or class polygons, not both")
        if raster is not None:
            return ClassRaster(raster.source()), raster.source()
        if polygons is None:
            return None, "none"
        fields = self.parameterAsFields(parameters, "CLASS_FIELD", context)
        if not fields:
            raise InputError("name the class field of the class polygons")
        geometries, values = [], []
        for feature in polygons.getFeatures():
            if feature.hasGeometry():
                geometries.append(bytes(feature.geometry().asWkb()))
                values.append(feature[fields[0]])
        return PolygonClasses(geometries, values, polygons.crs().toWkt()), f"{polygons.source()} ({fields[0]})"

    def execute(self, parameters, context, feedback):
        reference = self.parameterAsRasterLayer(parameters, "REFERENCE", context).source()
        points = self.parameterAsFile(parameters, "POINTS", context) or None
        dem_layer = self.parameterAsRasterLayer(parameters, "DEM", context)
        dem = dem_layer.source() if dem_layer is not None else None
        datums = {key: HEIGHT_TYPES[self.parameterAsEnum(parameters, key, context)]
                  for key in ("REFERENCE_HEIGHTS", "POINTS_HEIGHTS", "DEM_HEIGHTS")}
        classes, class_source = self._classes(parameters, context)
        threshold = self.parameterAsDouble(parameters, "SLOPE_THRESHOLD", context)
        dh_path = self.parameterAsOutputLayer(parameters, "DH", context)
        if dh_path and dem is None:
            raise InputError("the dh raster needs a DEM input: give a DEM or leave the dh raster unset")
        assessed = assess(reference, points=points, dem=dem, reference_datum=datums["REFERENCE_HEIGHTS"],
                          points_datum=datums["POINTS_HEIGHTS"], dem_datum=datums["DEM_HEIGHTS"], classes=classes,
                          slope_threshold=threshold, feedback=progress.scaled(feedback, 0, 70),
                          reference_nodata=self.parameterAsOptionalDouble(parameters, "REFERENCE_NODATA", context))
        used = [("reference", f"{reference} ({datums['REFERENCE_HEIGHTS']} heights)")]
        if points:
            used.append(("point cloud", f"{points} ({datums['POINTS_HEIGHTS']} heights)"))
        if dem:
            used.append(("DEM", f"{dem} ({datums['DEM_HEIGHTS']} heights; reference resampled onto its grid)"))
        used += [("classes", class_source), ("slope threshold", f"{threshold:g} deg")]
        from ...algorithms.quality import report   # matplotlib: loaded on use, not with the plugin
        feedback.pushInfo(report.text(assessed, used))
        progress.step(feedback, 75, "drawing the figures")
        out = {"REPORT": report.write_report(self.parameterAsFileOutput(parameters, "REPORT", context),
                                             "Accuracy assessment", assessed, used)}
        progress.step(feedback, 95)
        table = self.parameterAsFileOutput(parameters, "TABLE", context)
        if table:
            out["TABLE"] = report.write_csv(table, assessed)
        if dh_path:
            grid = next(a.differences.grid for a in assessed if a.differences.grid is not None)
            out["DH"] = write_dh_raster(dh_path, grid)
            style_on_completion(context, dh_path, "dh.qml")
        return out
