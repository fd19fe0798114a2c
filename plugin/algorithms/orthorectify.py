"""pushbroom:orthorectify — orthoimage by the indirect method (H 4.1; algorithms/ortho) with a block's
(adjusted) sensor model or an image's own orientation, on a DEM, as a tiled GeoTIFF with overviews."""
from qgis.core import (
    QgsProcessingOutputNumber,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterCrs,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFile,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
)

from ...algorithms import progress, sensors
from ...algorithms.block import Block
from ...algorithms.errors import InputError
from ...algorithms.ortho import load_dem, orthorectify
from ...algorithms.ortho.orthorectify import VERTICAL
from ...algorithms.ortho.resampling import METHODS
from .base import PushbroomAlgorithm
from .dem_nodata import nodata_parameter

Number = QgsProcessingParameterNumber
RESAMPLING = tuple(METHODS)


class Orthorectify(PushbroomAlgorithm):
    NAME = "orthorectify"
    DISPLAY_NAME = "Orthorectify image"
    GROUP = "Surface"
    GROUP_ID = "surface"
    HELP = ("Orthoimage of one image by the indirect method (Hofmann et al., 4.1): every output cell's ground point "
            "(height from the DEM) is projected into the image with the sensor model, and the image is resampled "
            "there (bilinear or bicubic, Keys a = -0.5). The model is the block's (adjusted) model of the named "
            "image, or the image's own orientation (DIMAP, RPC, .geom or an orientation file given). The DEM may be "
            "in any CRS, with ellipsoidal or EGM96 heights; heights outside -500 .. 9000 m (voids not flagged as "
            "nodata) are reported, and a void value can be declared as the DEM's nodata. Ground-to-image runs "
            "exactly on a coarse grid of each 512-cell tile and is interpolated in between (bilinear in position, "
            "linear in height); the step is "
            "halved until the interpolation error, checked exactly at the coarse cells' midpoints and at "
            "mid-height, is below the bound (default 0.01 px); the achieved bound is reported. Cells outside the "
            "image (or occluded by the DEM, when asked) are nodata. Output: tiled GeoTIFF of the image's data type "
            "with overviews, in the CRS given (default: the UTM zone of the footprint) with the cell size given "
            "(default: the image's ground sampling distance).")

    def initAlgorithm(self, config=None):
        self.addParameter(QgsProcessingParameterFile("BLOCK", "Block (empty: the image's own orientation)",
                                                     extension="gpkg", optional=True))
        self.addParameter(QgsProcessingParameterString("IMAGE_NAME", "Image name in the block", optional=True))
        self.addParameter(QgsProcessingParameterRasterLayer("IMAGE", "Image (without a block)", optional=True))
        self.addParameter(QgsProcessingParameterFile(
            "ORIENTATION", "Orientation file (empty: found beside the image)", optional=True))
        self.addParameter(QgsProcessingParameterRasterLayer("DEM", "DEM"))
        self.addParameter(QgsProcessingParameterEnum("DEM_HEIGHTS", "DEM heights", ["ellipsoidal (WGS 84)", "EGM96"],
                                                     defaultValue=0))
        self.addParameter(QgsProcessingParameterCrs("CRS", "Output CRS (empty: UTM zone of the footprint)", None,
                                                    optional=True))
        self.addParameter(Number("CELL_SIZE", "Cell size in CRS units (empty: ground sampling distance)",
                                 Number.Double, None, optional=True, minValue=0.0))
        self.addParameter(QgsProcessingParameterEnum("RESAMPLING", "Resampling", list(RESAMPLING), defaultValue=0))
        self.addParameter(QgsProcessingParameterBoolean("OCCLUSION", "Occluded cells as nodata", False))
        self.addAdvancedParameters([
            Number("MAX_ERROR", "Bound of the coarse-grid interpolation error (px)", Number.Double, 0.01,
                   minValue=1e-6),
            Number("THREADS", "Threads", Number.Integer, 1, minValue=1),
            nodata_parameter(),
        ])
        self.addParameter(QgsProcessingParameterRasterDestination("OUTPUT", "Orthoimage"))
        self.addOutput(QgsProcessingOutputNumber("BOUND", "Achieved interpolation error bound (px)"))
        self.addOutput(QgsProcessingOutputNumber("CELLS", "Cells with image values"))

    def image_and_model(self, parameters, context):
        """(image path, sensor model): the block's model of IMAGE_NAME, or the IMAGE's own orientation."""
        path = self.parameterAsFile(parameters, "BLOCK", context)
        blk = Block(path)
        name = self.parameterAsString(parameters, "IMAGE_NAME", context).strip()
        if path:
            rows = blk.images()
            chosen = [r for r in rows if r["name"] == name]
            if not chosen:
                raise InputError(f"give the name of one of the block's images ({', '.join(r['name'] for r in rows)})")
            return chosen[0]["image_path"], blk.model(chosen[0]["id"])
        layer = self.parameterAsRasterLayer(parameters, "IMAGE", context)
        if layer is None:
            raise InputError("give a block and an image name, or an image")
        orientation = self.parameterAsFile(parameters, "ORIENTATION", context)
        image = layer.source()
        return image, sensors.load(orientation or image, image=image if orientation else None)

    def execute(self, parameters, context, feedback):
        image, model = self.image_and_model(parameters, context)
        dem = load_dem(self.parameterAsRasterLayer(parameters, "DEM", context).source(),
                       VERTICAL[self.parameterAsEnum(parameters, "DEM_HEIGHTS", context)],
                       self.parameterAsOptionalDouble(parameters, "DEM_NODATA", context))
        progress.warn(feedback, dem.implausible)
        crs = self.parameterAsCrsDefinition(parameters, "CRS", context)
        output = self.parameterAsOutputLayer(parameters, "OUTPUT", context)
        result = orthorectify(
            image, model, dem, output, crs=crs,
            cell_size=self.parameterAsOptionalDouble(parameters, "CELL_SIZE", context),
            resampling_method=RESAMPLING[self.parameterAsEnum(parameters, "RESAMPLING", context)],
            occlusion_mask=self.parameterAsBool(parameters, "OCCLUSION", context),
            max_error=self.parameterAsDouble(parameters, "MAX_ERROR", context),
            threads=self.parameterAsInt(parameters, "THREADS", context), feedback=feedback)
        return {"OUTPUT": output, "BOUND": result.bound, "CELLS": result.cells}
