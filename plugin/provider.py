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

    def loadAlgorithms(self):
        from .algorithms import algorithm_classes
        for cls in algorithm_classes():
            self.addAlgorithm(cls())
