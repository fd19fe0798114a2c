"""The Processing provider `pushbroom` ("Pushbroom photogrammetry")."""

from qgis.core import QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from ..resource_files import resource_path


class PushbroomProvider(QgsProcessingProvider):
    """Holds one instance of every Pushbroom algorithm."""

    def id(self):
        return "pushbroom"

    def name(self):
        return "Pushbroom photogrammetry"

    def longName(self):
        return "Pushbroom photogrammetry for linear-array satellite imagery"

    def icon(self):
        return QIcon(resource_path("icons", "pushbroom.svg"))

    def supportedOutputRasterLayerExtensions(self) -> list:
        """Every raster a step writes is a GeoTIFF: the toolbox's file dialogs offer only that, and a raster
        output named otherwise is refused before the step runs (algorithms/destinations.py)."""
        from ..algorithms.destinations import RASTER_EXTENSIONS

        return list(RASTER_EXTENSIONS)

    def supportedOutputVectorLayerExtensions(self) -> list:
        """The formats of the one vector output (bundleadjust's residual vectors), likewise."""
        from ..algorithms.adjustment.residual_vectors import FORMATS

        return list(FORMATS)

    def loadAlgorithms(self):
        from .algorithms import algorithm_classes

        for cls in algorithm_classes():
            self.addAlgorithm(cls())
