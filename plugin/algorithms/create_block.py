"""pushbroom:createblock — images and their orientation into a block GeoPackage."""
from qgis.core import (QgsProcessing, QgsProcessingParameterBoolean, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterMultipleLayers, QgsProcessingParameterNumber,
                       QgsProcessingParameterRasterLayer, QgsProcessingOutputVectorLayer, QgsProcessingUtils)

from ...algorithms import progress, sensors
from ...algorithms.block import Block
from ...algorithms.dem import Dem
from ...algorithms.errors import PushbroomError
from ..styles import load_styled
from .base import PushbroomAlgorithm
from .dem_nodata import nodata_parameter


class CreateBlock(PushbroomAlgorithm):
    NAME = "createblock"
    DISPLAY_NAME = "Create block"
    GROUP = "Block"
    GROUP_ID = "block"
    HELP = ("Creates a block GeoPackage from images and their supplied orientation: SPOT 1-5 DIMAP "
            "(METADATA.DIM beside IMAGERY.TIF), rasters with RPC tags or _RPC.TXT/.RPB, or OSSIM .geom "
            "files of the same name. The footprint of each image is projected on the DEM (ellipsoidal "
            "heights) or at the mean height and loaded as a polygon layer; DEM heights outside -500 .. 9000 m "
            "(voids not flagged as nodata) are reported, and a void value can be declared as the DEM's nodata. "
            "An existing block is only replaced when 'Overwrite' is checked.")

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS API)
        self.addParameter(QgsProcessingParameterMultipleLayers("IMAGES", "Images", QgsProcessing.TypeRaster))
        self.addParameter(QgsProcessingParameterMultipleLayers(
            "ORIENTATION", "Orientation files (one per image, same order; found beside the images if empty)",
            QgsProcessing.TypeFile, optional=True))
        self.addParameter(QgsProcessingParameterRasterLayer(
            "DEM", "DEM for the footprints (ellipsoidal heights)", optional=True))
        self.addParameter(QgsProcessingParameterNumber(
            "HEIGHT", "Mean ellipsoidal height when no DEM is given (m)", QgsProcessingParameterNumber.Double, 0.0))
        self.addParameter(QgsProcessingParameterBoolean("OVERWRITE", "Overwrite an existing block", False))
        self.addAdvancedParameters([nodata_parameter()])
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Block", "GeoPackage (*.gpkg)"))
        self.addOutput(QgsProcessingOutputVectorLayer("FOOTPRINTS", "Footprints", QgsProcessing.TypeVectorPolygon))

    def checkParameterValues(self, parameters, context):  # noqa: N802 (QGIS API)
        """QGIS's check; where it refuses the images, the engine's reason for a file path that is no
        layer (a missing file, a SPOT DIMAP product without its raster) instead of 'Incorrect parameter
        value for IMAGES'."""
        ok, message = super().checkParameterValues(parameters, context)
        if not ok:
            values = parameters.get("IMAGES")
            for value in values if isinstance(values, (list, tuple)) else [values]:
                if isinstance(value, str) and QgsProcessingUtils.mapLayerFromString(value, context, False) is None:
                    try:
                        sensors.check_image(value)
                    except PushbroomError as exc:
                        return False, str(exc)
        return ok, message

    def execute(self, parameters, context, feedback):
        images = [layer.source() for layer in self.parameterAsLayerList(parameters, "IMAGES", context)]
        orientation = [p for p in self.parameterAsFileList(parameters, "ORIENTATION", context) if p]
        dem_layer = self.parameterAsRasterLayer(parameters, "DEM", context)
        dem = None
        if dem_layer is not None:
            dem = Dem.from_file(dem_layer.source(), self.parameterAsOptionalDouble(parameters, "DEM_NODATA", context))
            progress.warn(feedback, dem.implausible)
        output = self.parameterAsFileOutput(parameters, "OUTPUT", context)
        opened = Block.open_images(images, orientation)
        blk = Block.create(output, opened, height=self.parameterAsDouble(parameters, "HEIGHT", context), dem=dem,
                           overwrite=self.parameterAsBool(parameters, "OVERWRITE", context), feedback=feedback)
        footprints = blk.layer_source("footprints")
        load_styled(context, footprints, "Footprints", "FOOTPRINTS", "footprints.qml")
        feedback.pushInfo(f"block {output}: " + ", ".join(f"{name} ({model.size[0]} x {model.size[1]})"
                                                          for name, _, _, model in opened))
        return {"OUTPUT": output, "FOOTPRINTS": footprints}
