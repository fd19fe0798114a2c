"""pushbroom:interpolatedem: a DEM from a point cloud (algorithms/surface/dem_tiles.py: a TIN, or per-cell
medians for dense points)."""

from qgis.core import (
    QgsProcessing,
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP

from ...algorithms import destinations
from ...algorithms.surface.dem_tiles import dem_from_point_cloud, mask_output
from ...algorithms.surface.tin_dem import MAX_RADIUS, DemParams
from ..styles import style_on_completion
from .base import PushbroomAlgorithm, cog_parameter, execution_choice, execution_parameters, translate, translated

Number = QgsProcessingParameterNumber
#: height datums: (engine key, label)
DATUMS = (
    ("ellipsoidal", QT_TRANSLATE_NOOP("Pushbroom", "WGS 84 ellipsoidal height")),
    ("egm96", QT_TRANSLATE_NOOP("Pushbroom", "EGM96 (orthometric) height")),
)
#: interpolation methods: (engine key, label)
METHODS = (
    ("tin", QT_TRANSLATE_NOOP("Pushbroom", "TIN of the points (sparse points: region growing, coarse-to-fine)")),
    ("cells", QT_TRANSLATE_NOOP("Pushbroom", "Per-cell median (dense points: the dense matching strategy)")),
)


class InterpolateDem(PushbroomAlgorithm):
    NAME = "interpolatedem"
    DISPLAY_NAME = QT_TRANSLATE_NOOP("Pushbroom", "Interpolate DEM")
    GROUP_ID = "surface"

    # parameter and output keys: the names Processing, models and qgis_process use
    INPUT = "INPUT"
    BREAKLINES = "BREAKLINES"
    CRS = "CRS"
    CELL = "CELL"
    METHOD = "METHOD"
    DATUM = "DATUM"
    INPUT_CRS = "INPUT_CRS"
    MAX_EDGE = "MAX_EDGE"
    BLUNDER_K = "BLUNDER_K"
    ITERATIONS = "ITERATIONS"
    TILE = "TILE"
    EXECUTION = "EXECUTION"
    DASK_ADDRESS = "DASK_ADDRESS"
    DASK_WAIT = "DASK_WAIT"
    WORKERS = "WORKERS"
    FALLBACK = "FALLBACK"
    RADIUS = "RADIUS"
    FILL = "FILL"
    OUTPUT = "OUTPUT"
    PRECISION = "PRECISION"
    COUNT = "COUNT"
    MASK = "MASK"
    COG = "COG"
    POINTS = "POINTS"
    REMOVED = "REMOVED"
    FILLED = "FILLED"

    def initAlgorithm(self, config=None):
        d = DemParams()
        self.addParameter(
            QgsProcessingParameterFile(
                self.INPUT,
                translate("Pushbroom", "Point cloud"),
                fileFilter=translate("Pushbroom", "Point clouds (*.las *.laz *.gpkg *.shp *.geojson);;All files (*)"),
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSource(
                self.BREAKLINES,
                translate("Pushbroom", "Breaklines (3-D lines)"),
                [QgsProcessing.TypeVectorLine],
                optional=True,
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, translate("Pushbroom", "Output CRS (empty: the UTM zone of the points)"), None, optional=True
            )
        )
        self.addParameter(
            Number(
                self.CELL, translate("Pushbroom", "Cell size (output CRS units)"), Number.Double, d.cell, minValue=1e-6
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.METHOD, translate("Pushbroom", "Method"), [translated(t) for _, t in METHODS], defaultValue=0
            )
        )
        self.addParameter(
            QgsProcessingParameterEnum(
                self.DATUM, translate("Pushbroom", "Height datum"), [translated(t) for _, t in DATUMS], defaultValue=0
            )
        )
        self.addParameter(cog_parameter(self))
        self.addAdvancedParameters(
            [
                QgsProcessingParameterCrs(
                    self.INPUT_CRS,
                    translate("Pushbroom", "Point cloud CRS (empty: the file's own)"),
                    None,
                    optional=True,
                ),
                Number(
                    self.MAX_EDGE,
                    translate("Pushbroom", "Maximum triangle edge (empty: 3 cells or 2.5 point spacings)"),
                    Number.Double,
                    None,
                    optional=True,
                    minValue=0.0,
                ),
                Number(
                    self.BLUNDER_K,
                    translate("Pushbroom", "Blunder threshold k (robust sigmas; 0: no filter)"),
                    Number.Double,
                    d.k,
                    minValue=0.0,
                ),
                Number(
                    self.ITERATIONS,
                    translate("Pushbroom", "Blunder filter iterations"),
                    Number.Integer,
                    d.iterations,
                    minValue=1,
                ),
                Number(self.TILE, translate("Pushbroom", "Tile size (cells)"), Number.Integer, d.tile, minValue=16),
                QgsProcessingParameterBoolean(
                    self.FALLBACK,
                    translate("Pushbroom", "Per-cell method: unrefined points where a cell has no refined one"),
                    d.fallback,
                ),
                Number(
                    self.RADIUS,
                    translate("Pushbroom", "Per-cell method: borrow points within this many cells (0: none)"),
                    Number.Integer,
                    d.radius,
                    minValue=0,
                    maxValue=MAX_RADIUS,
                ),
                Number(
                    self.FILL,
                    translate("Pushbroom", "Per-cell method: fill gaps within this many cells (0: none)"),
                    Number.Double,
                    d.fill,
                    minValue=0.0,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, translate("Pushbroom", "DEM")))
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.PRECISION, translate("Pushbroom", "Precision raster"), optional=True, createByDefault=False
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.COUNT,
                translate("Pushbroom", "Points per cell (per-cell method)"),
                optional=True,
                createByDefault=False,
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.MASK,
                translate("Pushbroom", "Cell mask (per-cell method: 0 own points, 2 borrowed, 1 filled, 255 gap)"),
                optional=True,
                createByDefault=False,
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.POINTS, translate("Pushbroom", "Points in the DEM")))
        self.addOutput(QgsProcessingOutputNumber(self.FILLED, translate("Pushbroom", "Gap cells filled")))
        self.addOutput(QgsProcessingOutputNumber(self.REMOVED, translate("Pushbroom", "Blunders (outliers) removed")))

    def extra_destinations(self, parameters, context) -> list:
        """The cell mask the per-cell method writes beside the DEM when it fills gaps and MASK is not given."""
        output = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        method = METHODS[self.parameterAsEnum(parameters, self.METHOD, context)][0]
        beside = mask_output(output, DemParams(fill=self.parameterAsDouble(parameters, self.FILL, context)))
        if (
            method != "cells"
            or not output
            or beside is None
            or self.parameterAsOutputLayer(parameters, self.MASK, context)
        ):
            return []
        return [destinations.Destination(beside, f"{self.MASK} (cell mask, beside the DEM)")]

    def dem_params(self, parameters, context):
        """DemParams of the parameters."""
        values = self.parameterValues(
            parameters,
            context,
            cell=self.CELL,
            datum=self.DATUM,
            max_edge=self.MAX_EDGE,
            k=self.BLUNDER_K,
            iterations=self.ITERATIONS,
            tile=self.TILE,
            method=self.METHOD,
            fallback=self.FALLBACK,
            radius=self.RADIUS,
            fill=self.FILL,
        )
        values.update(datum=DATUMS[values["datum"]][0], method=METHODS[values["method"]][0])
        return DemParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            input_crs=self.parameterAsCrsDefinition(parameters, self.INPUT_CRS, context),
            execution=execution_choice(self, parameters, context),
            cog=self.parameterAsBool(parameters, self.COG, context),
            **values,
        )

    def breaklines(self, parameters, context, feedback):
        """(path, layer name or None) of the BREAKLINES layer as a file OGR reads, or None where none is given."""
        if not parameters.get(self.BREAKLINES):
            return None
        path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
            parameters, self.BREAKLINES, context, ["gpkg", "shp"], "gpkg", feedback
        )
        return (path, layer or None)

    def execute(self, parameters, context, feedback):
        params = self.dem_params(parameters, context)
        breaklines = self.breaklines(parameters, context, feedback)
        out, precision, count, mask = (
            self.parameterAsOutputLayer(parameters, key, context)
            for key in (self.OUTPUT, self.PRECISION, self.COUNT, self.MASK)
        )
        source = self.parameterAsFile(parameters, self.INPUT, context)
        result = dem_from_point_cloud(
            source,
            out,
            params,
            breaklines,
            precision or None,
            feedback,
            count_path=count or None,
            mask_path=mask or None,
        )
        style_on_completion(context, out, "dem.qml")
        return self.given(self.outputs(result, out, precision, count))

    def outputs(self, result, out, precision, count):
        """The algorithm's outputs of the engine's DemResult `result` and the rasters written."""
        return {
            self.OUTPUT: out,
            self.POINTS: result.points,
            self.REMOVED: sum(result.removed),
            self.PRECISION: precision,
            self.COUNT: count,
            self.MASK: result.mask_path,
            self.FILLED: result.filled,
        }
