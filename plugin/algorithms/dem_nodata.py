"""The optional, advanced 'nodata value' parameter of the algorithms that read a DEM: declares a value of
voids that the raster does not flag as nodata (SRTM's -32768), which the engine then reads as NaN
(dem_store.store_dem, quality assessment's reference)."""

from __future__ import annotations

from qgis.core import QgsProcessingParameterNumber

from .base import translate


def nodata_parameter(name: str = "DEM_NODATA", what: str | None = None) -> QgsProcessingParameterNumber:
    """The parameter `name` declaring the nodata value of the `what` raster (translated; default the DEM), empty: the
    raster's own."""
    what = what or translate("Pushbroom", "DEM")
    return QgsProcessingParameterNumber(
        name,
        translate("Pushbroom", "Nodata value of the {} (voids its file does not flag, e.g. -32768)").format(what),
        QgsProcessingParameterNumber.Double,
        None,
        optional=True,
    )
