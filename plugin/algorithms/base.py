"""Common base of the Processing algorithms: naming, help, icon, and the translation of the
engine's errors into QgsProcessingException (a clear message, never a traceback)."""
from qgis.core import QgsProcessingAlgorithm, QgsProcessingException, QgsProcessingParameterDefinition
from qgis.PyQt.QtGui import QIcon

from ...algorithms.errors import PushbroomError
from ..plugin import resource_path


class PushbroomAlgorithm(QgsProcessingAlgorithm):
    """Subclasses set NAME, DISPLAY_NAME, GROUP, GROUP_ID, HELP and implement `execute`."""

    NAME = ""
    DISPLAY_NAME = ""
    GROUP = ""
    GROUP_ID = ""
    HELP = ""

    def createInstance(self):  # noqa: N802 (QGIS API)
        return type(self)()

    def name(self):
        return self.NAME

    def displayName(self):  # noqa: N802 (QGIS API)
        return self.DISPLAY_NAME

    def group(self):
        return self.GROUP

    def groupId(self):  # noqa: N802 (QGIS API)
        return self.GROUP_ID

    def shortHelpString(self):  # noqa: N802 (QGIS API)
        return self.HELP

    def addAdvancedParameters(self, parameters):  # noqa: N802 (QGIS naming)
        """Add `parameters` flagged as advanced (folded away in the dialog)."""
        for parameter in parameters:
            parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(parameter)

    def parameterAsOptionalDouble(self, parameters, key, context):  # noqa: N802 (QGIS naming)
        """The number of an optional parameter, or None where it is not set."""
        value = parameters.get(key)
        return None if value is None or value == "" else self.parameterAsDouble(parameters, key, context)

    def parameterAsCrsDefinition(self, parameters, key, context):  # noqa: N802 (QGIS naming)
        """The CRS of a CRS parameter as the engine takes it (authority id, else WKT), or None where unset."""
        crs = self.parameterAsCrs(parameters, key, context)
        return (crs.authid() or crs.toWkt(crs.WKT_PREFERRED)) if crs.isValid() else None

    def icon(self):
        return QIcon(resource_path("icons", "pushbroom.svg"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS API)
        try:
            return self.execute(parameters, context, feedback)
        except PushbroomError as exc:
            raise QgsProcessingException(str(exc)) from exc

    def execute(self, parameters, context, feedback):
        raise NotImplementedError
