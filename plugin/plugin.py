"""The plugin object QGIS creates through classFactory."""

import os

from qgis.core import QgsApplication, QgsSettings
from qgis.PyQt.QtCore import QCoreApplication, QLocale, QTranslator

PIP_HINT = "python3 -m pip install numba"
APT_HINT = "sudo apt-get install python3-numba python3-scipy python3-gdal"


def missing_dependencies():
    """Names of required Python packages that cannot be imported."""
    missing = []
    for name in ("numpy", "numba", "scipy", "osgeo"):
        try:
            __import__(name)
        except ImportError:
            missing.append(name)
    return missing


def install_translator(locale=None):
    """The QTranslator of i18n/pushbroom_<language>.qm for QGIS's user locale (`locale`: another one), installed; None
    where there is no such file (English, the source texts, is shown)."""
    locale = locale or QgsSettings().value("locale/userLocale", "") or QLocale.system().name()
    path = os.path.join(os.path.dirname(__file__), os.pardir, "i18n", f"pushbroom_{str(locale)[:2]}.qm")
    translator = QTranslator()
    if not os.path.isfile(path) or not translator.load(path):
        return None
    QCoreApplication.installTranslator(translator)
    return translator


def create_plugin(iface):
    """The real plugin, or a stand-in that explains which packages are missing."""
    missing = missing_dependencies()
    if missing:
        return MissingDependencyPlugin(iface, missing)
    return PushbroomPlugin(iface)


class PushbroomPlugin:
    """Registers the Processing provider (kept alive by `self.provider`) and, in the QGIS desktop, the
    "Measure control points..." action (plugin/measure_action.py); removes both on unload."""

    def __init__(self, iface):
        self.iface = iface
        self.provider = None
        self.measure = None
        self.translator = install_translator()

    def initProcessing(self):
        from .provider import PushbroomProvider

        if QgsApplication.instance() is not None and QgsApplication.instance().platform() == "qgis_process":
            from .gdal_messages import install_console_filter

            install_console_filter()
        self.provider = PushbroomProvider()
        QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):
        self.initProcessing()
        if self.iface is not None:
            from .measure_action import MeasureAction

            self.measure = MeasureAction(self.iface)

    def unload(self):
        if self.measure is not None:
            self.measure.unload()
            self.measure = None
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
        if self.translator is not None:
            QCoreApplication.removeTranslator(self.translator)
            self.translator = None


class MissingDependencyPlugin:
    """Loaded instead of the plugin when a dependency is missing: one clear message, no traceback."""

    def __init__(self, iface, missing):
        self.iface = iface
        self.missing = missing

    def message(self):
        packages = ", ".join(self.missing)
        return (
            f"Pushbroom needs the Python package(s) {packages}, which QGIS's Python cannot import. "
            f"Install them for the Python that runs QGIS: on Debian/Ubuntu `{APT_HINT}`, "
            f"elsewhere (Windows OSGeo4W shell, macOS) `{PIP_HINT}`; then restart QGIS."
        )

    def initGui(self):
        from qgis.core import Qgis, QgsMessageLog

        QgsMessageLog.logMessage(self.message(), "Pushbroom", Qgis.Critical)
        if self.iface is not None and hasattr(self.iface, "messageBar"):
            self.iface.messageBar().pushMessage("Pushbroom", self.message(), level=Qgis.Critical, duration=0)

    def initProcessing(self):
        pass

    def unload(self):
        pass
