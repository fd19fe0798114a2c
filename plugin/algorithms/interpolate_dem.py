"""pushbroom:interpolatedem — a DEM from a point cloud: Delaunay TIN with optional breaklines,
blunder filter, linear interpolation on a regular grid (algorithms/surface/tin_dem.py)."""
from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
)

from ...algorithms import progress
from ...algorithms.surface import point_input, tin_dem
from ..styles import style_on_completion
from .base import PushbroomAlgorithm

Number = QgsProcessingParameterNumber
DATUMS = (("ellipsoidal", "WGS 84 ellipsoidal height"), ("egm96", "EGM96 (orthometric) height"))


class InterpolateDem(PushbroomAlgorithm):
    NAME = "interpolatedem"
    DISPLAY_NAME = "Interpolate DEM (TIN)"
    GROUP = "Surface"
    GROUP_ID = "surface"
    HELP = ("A DEM from a point cloud (Kornus et al. 2006, 3.6): the Delaunay TIN of the points (LAS/LAZ or a "
            "3-D point layer such as the GeoPackage of pushbroom:intersectpoints; z = WGS 84 ellipsoidal height) "
            "is interpolated linearly on a regular grid in the output CRS (default: the UTM zone of the points). "
            "Triangles with an edge longer than the maximum edge length (default: the larger of 3 cells and 2.5 "
            "point spacings) are left as gaps: no surface is invented over unmatched water or forest. Blunders are "
            "removed first: points whose height departs from the least-squares plane through their TIN neighbours "
            "by more than k robust sigmas (NMAD = 1.4826 x the median absolute deviation of all residuals; the "
            "largest of neighbouring candidates per iteration); the log gives the count. Breaklines (3-D lines) "
            "are densified and split until no point encroaches on them, so no triangle crosses them (conforming "
            "Delaunay); points very close to a breakline give way to it. Heights "
            "are ellipsoidal or EGM96 (H = h - N, PROJ's EGM96 grid). The optional precision raster holds the "
            "points' sigma_h interpolated on the TIN where the cloud has it, otherwise the distance to the "
            "nearest point. A point cloud without a CRS (or with coordinates that cannot be in its CRS, such as "
            "degrees labelled UTM) is refused; its CRS can be given. Output: tiled Float32 GeoTIFF with overviews, "
            "nodata -32767.")

    def initAlgorithm(self, config=None):
        self.addParameter(QgsProcessingParameterFile(
            "INPUT", "Point cloud", fileFilter="Point clouds (*.las *.laz *.gpkg *.shp *.geojson);;All files (*)"))
        self.addParameter(QgsProcessingParameterFeatureSource(
            "BREAKLINES", "Breaklines (3-D lines)", [QgsProcessing.TypeVectorLine], optional=True))
        self.addParameter(QgsProcessingParameterCrs("CRS", "Output CRS (empty: the UTM zone of the points)", None,
                                                    optional=True))
        self.addParameter(Number("CELL", "Cell size (output CRS units)", Number.Double, 10.0, minValue=1e-6))
        self.addParameter(QgsProcessingParameterEnum("DATUM", "Height datum", [t for _, t in DATUMS], defaultValue=0))
        self.addAdvancedParameters([
            QgsProcessingParameterCrs("INPUT_CRS", "Point cloud CRS (empty: the file's own)", None, optional=True),
            Number("MAX_EDGE", "Maximum triangle edge (empty: 3 cells or 2.5 point spacings); longer triangles "
                   "are gaps", Number.Double, None, optional=True, minValue=0.0),
            Number("BLUNDER_K", "Blunder threshold k (robust sigmas; 0: no filter)", Number.Double, 4.0, minValue=0.0),
            Number("ITERATIONS", "Blunder filter iterations", Number.Integer, 3, minValue=1),
        ])
        self.addParameter(QgsProcessingParameterRasterDestination("OUTPUT", "DEM"))
        self.addParameter(QgsProcessingParameterRasterDestination("PRECISION", "Precision raster", optional=True,
                                                                  createByDefault=False))
        self.addOutput(QgsProcessingOutputNumber("POINTS", "Points in the TIN"))
        self.addOutput(QgsProcessingOutputNumber("REMOVED", "Blunders removed"))

    def execute(self, parameters, context, feedback):
        points = point_input.read_points(self.parameterAsFile(parameters, "INPUT", context),
                                         self.parameterAsCrsDefinition(parameters, "INPUT_CRS", context))
        crs = self.parameterAsCrsDefinition(parameters, "CRS", context)
        cell = self.parameterAsDouble(parameters, "CELL", context)
        lines, lines_srs = [], None
        if parameters.get("BREAKLINES"):
            path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
                parameters, "BREAKLINES", context, ["gpkg", "shp"], "gpkg", feedback)
            lines, lines_srs = point_input.read_breaklines(path, layer or None)
        precision_path = self.parameterAsOutputLayer(parameters, "PRECISION", context)
        result = tin_dem.interpolate_dem(
            points, cell=cell, crs=crs, datum=DATUMS[self.parameterAsEnum(parameters, "DATUM", context)][0],
            max_edge=self.parameterAsOptionalDouble(parameters, "MAX_EDGE", context),
            k=self.parameterAsDouble(parameters, "BLUNDER_K", context),
            iterations=self.parameterAsInt(parameters, "ITERATIONS", context),
            breaklines=lines, breakline_srs=lines_srs,
            precision=bool(precision_path), feedback=progress.scaled(feedback, 0, 85))
        out = self.parameterAsOutputLayer(parameters, "OUTPUT", context)
        tin_dem.write_dem(result, out, precision_path or None, feedback=progress.scaled(feedback, 85, 100))
        feedback.pushInfo(result.summary())
        style_on_completion(context, out, "dem.qml")
        results = {"OUTPUT": out, "POINTS": result.points, "REMOVED": sum(result.removed)}
        if precision_path:
            results["PRECISION"] = precision_path
        return results
