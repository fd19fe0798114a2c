"""The optional, advanced 'nodata value' parameter of the algorithms that read a DEM: declares a value of
voids that the raster does not flag as nodata (SRTM's -32768), which the engine then reads as NaN
(dem_store.store_dem, quality assessment's reference)."""

from qgis.core import QgsProcessingParameterNumber


def nodata_parameter(name="DEM_NODATA", what="DEM"):
    """The parameter `name` declaring the nodata value of the `what` raster (empty: the raster's own)."""
    return QgsProcessingParameterNumber(
        name,
        f"Nodata value of the {what} (voids its file does not flag, e.g. -32768; empty: the file's own)",
        QgsProcessingParameterNumber.Double,
        None,
        optional=True,
    )
