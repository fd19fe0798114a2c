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

from ...algorithms import destinations
from ...algorithms.surface.dem_tiles import dem_from_point_cloud, mask_output
from ...algorithms.surface.tin_dem import MAX_RADIUS, DemParams
from ..styles import style_on_completion
from .base import PushbroomAlgorithm, execution_choice, execution_parameters

Number = QgsProcessingParameterNumber
#: height datums: (engine key, label)
DATUMS = (("ellipsoidal", "WGS 84 ellipsoidal height"), ("egm96", "EGM96 (orthometric) height"))
#: interpolation methods: (engine key, label)
METHODS = (
    ("tin", "TIN of the points (sparse points: region growing, coarse-to-fine)"),
    ("cells", "Per-cell median (dense points: the dense matching strategy)"),
)


class InterpolateDem(PushbroomAlgorithm):
    NAME = "interpolatedem"
    DISPLAY_NAME = "Interpolate DEM"
    GROUP_ID = "surface"

    KEYS = (
        "INPUT BREAKLINES CRS CELL METHOD DATUM INPUT_CRS MAX_EDGE BLUNDER_K ITERATIONS TILE EXECUTION "
        "DASK_ADDRESS DASK_WAIT WORKERS FALLBACK RADIUS FILL OUTPUT PRECISION COUNT MASK POINTS REMOVED FILLED"
    )

    def initAlgorithm(self, config=None):
        d, tr = DemParams(), self.tr
        self.addParameter(
            QgsProcessingParameterFile(
                self.INPUT,
                tr("Point cloud"),
                fileFilter=tr("Point clouds (*.las *.laz *.gpkg *.shp *.geojson);;All files (*)"),
            )
        )
        self.addParameter(
            QgsProcessingParameterFeatureSource(
                self.BREAKLINES, tr("Breaklines (3-D lines)"), [QgsProcessing.TypeVectorLine], optional=True
            )
        )
        self.addParameter(
            QgsProcessingParameterCrs(
                self.CRS, tr("Output CRS (empty: the UTM zone of the points)"), None, optional=True
            )
        )
        self.addParameter(Number(self.CELL, tr("Cell size (output CRS units)"), Number.Double, d.cell, minValue=1e-6))
        self.addParameter(
            QgsProcessingParameterEnum(self.METHOD, tr("Method"), [tr(t) for _, t in METHODS], defaultValue=0)
        )
        self.addParameter(
            QgsProcessingParameterEnum(self.DATUM, tr("Height datum"), [tr(t) for _, t in DATUMS], defaultValue=0)
        )
        self.addAdvancedParameters(
            [
                QgsProcessingParameterCrs(
                    self.INPUT_CRS, tr("Point cloud CRS (empty: the file's own)"), None, optional=True
                ),
                Number(
                    self.MAX_EDGE,
                    tr("Maximum triangle edge (empty: 3 cells or 2.5 point spacings); longer triangles are gaps"),
                    Number.Double,
                    None,
                    optional=True,
                    minValue=0.0,
                ),
                Number(
                    self.BLUNDER_K,
                    tr("Blunder threshold k (robust sigmas; 0: no filter); per cell with the per-cell method"),
                    Number.Double,
                    d.k,
                    minValue=0.0,
                ),
                Number(self.ITERATIONS, tr("Blunder filter iterations"), Number.Integer, d.iterations, minValue=1),
                Number(self.TILE, tr("Tile size (cells)"), Number.Integer, d.tile, minValue=16),
                QgsProcessingParameterBoolean(
                    self.FALLBACK,
                    tr("Per-cell method: a cell without a refined dense point takes the unrefined (semi-global) ones"),
                    d.fallback,
                ),
                Number(
                    self.RADIUS,
                    tr(
                        "Per-cell method: a cell without points takes those within this many cells "
                        "(0: none; flagged 2 in the mask raster)"
                    ),
                    Number.Integer,
                    d.radius,
                    minValue=0,
                    maxValue=MAX_RADIUS,
                ),
                Number(
                    self.FILL,
                    tr(
                        "Per-cell method: fill the gaps within this many cells (0: none; the filled "
                        "cells are flagged in the mask raster)"
                    ),
                    Number.Double,
                    d.fill,
                    minValue=0.0,
                ),
                *execution_parameters(self, d.execution.workers),
            ]
        )
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, tr("DEM")))
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.PRECISION, tr("Precision raster"), optional=True, createByDefault=False
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.COUNT, tr("Points per cell (per-cell method)"), optional=True, createByDefault=False
            )
        )
        self.addParameter(
            QgsProcessingParameterRasterDestination(
                self.MASK,
                tr(
                    "Cell mask (per-cell method: 0 own points, 2 points of the cells around, 1 filled, 255 gap; "
                    "empty: beside the DEM when filling)"
                ),
                optional=True,
                createByDefault=False,
            )
        )
        self.addOutput(QgsProcessingOutputNumber(self.POINTS, tr("Points in the DEM")))
        self.addOutput(QgsProcessingOutputNumber(self.FILLED, tr("Gap cells filled")))
        self.addOutput(QgsProcessingOutputNumber(self.REMOVED, tr("Blunders (outliers) removed")))

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

    def execute(self, parameters, context, feedback):
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
        params = DemParams(
            crs=self.parameterAsCrsDefinition(parameters, self.CRS, context),
            input_crs=self.parameterAsCrsDefinition(parameters, self.INPUT_CRS, context),
            execution=execution_choice(self, parameters, context),
            **values,
        )
        breaklines = None
        if parameters.get(self.BREAKLINES):
            path, layer = self.parameterAsCompatibleSourceLayerPathAndLayerName(
                parameters, self.BREAKLINES, context, ["gpkg", "shp"], "gpkg", feedback
            )
            breaklines = (path, layer or None)
        out = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        precision = self.parameterAsOutputLayer(parameters, self.PRECISION, context)
        count = self.parameterAsOutputLayer(parameters, self.COUNT, context)
        mask = self.parameterAsOutputLayer(parameters, self.MASK, context)
        result = dem_from_point_cloud(
            self.parameterAsFile(parameters, self.INPUT, context),
            out,
            params,
            breaklines,
            precision or None,
            feedback,
            count_path=count or None,
            mask_path=mask or None,
        )
        style_on_completion(context, out, "dem.qml")
        return self.given(
            {
                self.OUTPUT: out,
                self.POINTS: result.points,
                self.REMOVED: sum(result.removed),
                self.PRECISION: precision,
                self.COUNT: count,
                self.MASK: result.mask_path,
                self.FILLED: result.filled,
            }
        )
