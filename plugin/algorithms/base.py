"""Common base of the Processing algorithms: naming, help, icon, and what every algorithm does the same
way around its engine call:

- its outputs are checked before the work starts (algorithms/destinations.py): an output that would
  overwrite an input (by its real path, through a symbolic or a hard link, or inside a block's point
  folder) or another output, that is a device, a FIFO or a folder, whose extension its writer does not
  honour, or whose folder cannot be written fails in a second with a clear message, not after an hour
  of computing and never over the input;
- a CRS parameter the user filled in must be a valid CRS (an unknown code is an error, never the default);
- the engine's errors become QgsProcessingException, printed once (`_single_error`);
- a number parameter states its range in its help (which `qgis_process help` prints); a value out of it, or
  not a number (NaN passes QGIS's own check), is refused in Pushbroom's words with that range, and a raster
  QGIS cannot load is named with why: missing, a DIMAP product without its raster (`checkParameterValues`)."""

import functools
import math
import os
import re
from typing import Optional

from qgis.core import (
    QgsApplication,
    QgsProcessing,
    QgsProcessingAlgorithm,
    QgsProcessingException,
    QgsProcessingParameterBoolean,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterEnum,
    QgsProcessingParameterFeatureSource,
    QgsProcessingParameterFile,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterMultipleLayers,
    QgsProcessingParameterNumber,
    QgsProcessingParameterRasterDestination,
    QgsProcessingParameterRasterLayer,
    QgsProcessingParameterString,
    QgsProcessingParameterVectorDestination,
    QgsProcessingParameterVectorLayer,
    QgsProperty,
    QgsProviderRegistry,
)
from qgis.PyQt.QtCore import QT_TRANSLATE_NOOP, QCoreApplication, QEventLoop, QThread, QUrl
from qgis.PyQt.QtGui import QIcon

from ...algorithms import destinations, raster_cache, sensors
from ...algorithms.adjustment.control_points import HEIGHT_TYPES
from ...algorithms.block import Block
from ...algorithms.errors import InputError, PushbroomError
from ...algorithms.execution import Execution
from ...algorithms.gdal_errors import reported_here
from ...algorithms.task_runtime import BACKENDS, WORKERS_PER_CORE
from ...resource_files import resource_path
from ..console import line_buffered_stdout


def _single_error():
    """qgis_process echoes the message log's critical messages to stderr, and Processing logs a failed
    algorithm's exception there twice besides reporting it (as "ERROR: <message>", not in --json mode).
    Under qgis_process, which ends after the failure, stop the echo: at once where the report prints the
    message, after the first echo in --json mode."""
    app = QgsApplication.instance()
    if app is None or app.platform() != "qgis_process":
        return
    log = QgsApplication.messageLog()
    if "--json" not in app.arguments():
        log.blockSignals(True)
    else:
        log.messageReceived.connect(lambda *_: log.blockSignals(True))


#: the context of the texts that are not an algorithm's own: labels of choices and groups, marked for pylupdate5 by
#: QT_TRANSLATE_NOOP(CONTEXT, "...") where they are defined and shown through `translated`
CONTEXT = "Pushbroom"
translate = QCoreApplication.translate


def translated(text: str) -> str:
    """`text`, marked by QT_TRANSLATE_NOOP("Pushbroom", ...) where it is defined, in the user's language."""
    return QCoreApplication.translate(CONTEXT, text)


#: the toolbox groups: GROUP_ID -> display name
GROUPS = {
    "simulation": QT_TRANSLATE_NOOP("Pushbroom", "Simulation"),
    "block": QT_TRANSLATE_NOOP("Pushbroom", "Block"),
    "matching": QT_TRANSLATE_NOOP("Pushbroom", "Matching"),
    "adjustment": QT_TRANSLATE_NOOP("Pushbroom", "Adjustment"),
    "surface": QT_TRANSLATE_NOOP("Pushbroom", "Surface"),
}


def help_page(name):
    """Path of algorithm `name`'s documentation page, docs/steps/<name>.md."""
    return os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "docs", "steps", f"{name}.md")


@functools.cache
def parameter_help(name: str) -> dict:
    """{key: meaning} of the Parameters table of algorithm `name`'s page: a row's first cell names one or more
    keys in backticks, the column headed "Meaning" gives the help (Markdown's backticks dropped). The dialog
    shows it as the parameter's tooltip, `qgis_process help` under its description."""
    with open(help_page(name), encoding="utf-8") as f:
        text = f.read()
    table = text.split("## Parameters", 1)[1].split("\n## ", 1)[0] if "## Parameters" in text else ""
    found, meaning = {}, None
    for line in table.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0] == "Key":  # the header says which column is the meaning
            meaning = cells.index("Meaning") if "Meaning" in cells else None
        if meaning is None or len(cells) <= meaning or not cells[0].startswith("`"):
            continue
        for key in re.findall(r"`([A-Z0-9_]+)`", cells[0]):
            found[key] = cells[meaning].replace("`", "")
    return found


def short_help(name):
    """The first paragraph of algorithm `name`'s page (the summary under its heading), on one line."""
    with open(help_page(name), encoding="utf-8") as f:
        paragraphs = f.read().split("\n\n")
    return " ".join(paragraphs[1].split())


def _file_path(value):
    """`value` when it names a local file or folder (not a database, a URI or a memory layer), else None."""
    text = str(value or "").strip()
    if not text or text.startswith(("memory:", "postgres", "ogr:", "TEMPORARY_OUTPUT")) or "://" in text:
        return None
    return text


def _layer_path(layer) -> Optional[str]:
    """The file a map layer reads (its source without the provider's options, such as '|layername='), or None."""
    if layer is None:
        return None
    return QgsProviderRegistry.instance().decodeUri(layer.providerType(), layer.source()).get("path") or None


def filter_extensions(file_filter: str) -> tuple:
    """The extensions (lower case, without the dot) of a Qt file filter such as 'CSV files (*.csv)'; empty
    where the filter also admits any file ('All files (*.*)')."""
    if re.search(r"\(\*(\.\*)?\)|\*\.\*", file_filter):
        return ()
    return tuple(dict.fromkeys(e.lower() for e in re.findall(r"\*\.(\w+)", file_filter)))


def number_range(definition):
    """A number parameter's range in words: 'a number from 0 to 1', 'a whole number of at least 1', 'a number
    of at most 5', or 'a number' where it has none."""
    low = definition.minimum() if definition.minimum() > -1e300 else None
    high = definition.maximum() if definition.maximum() < 1e300 else None
    kind = "a whole number" if definition.dataType() == QgsProcessingParameterNumber.Integer else "a number"
    if low is not None and high is not None:
        return f"{kind} from {low:g} to {high:g}"
    if low is not None:
        return f"{kind} of at least {low:g}"
    if high is not None:
        return f"{kind} of at most {high:g}"
    return kind


def state_range(parameter):
    """`parameter`, where it is a number parameter with a range (number_range), with that range added to its help,
    which `qgis_process help` prints under its description and the dialog shows as its tooltip."""
    if isinstance(parameter, QgsProcessingParameterNumber):
        phrase = number_range(parameter)
        if phrase not in ("a number", "a whole number"):
            parameter.setHelp(" ".join(filter(None, [parameter.help(), f"Give {phrase}."])))
    return parameter


def number_problem(definition, value):
    """Why `value` of the number parameter `definition` is refused, in Pushbroom's words with its range, or ''
    (unset values are QGIS's to check against the default and the optional flag)."""
    if value is None or isinstance(value, QgsProperty) or (isinstance(value, str) and not value.strip()):
        return ""
    phrase = number_range(definition)
    try:
        number = float(value)
    except (TypeError, ValueError):
        return f"{definition.name()}: {str(value)[:40]!r} is not a number: give {phrase}"
    if math.isnan(number):
        return f"{definition.name()}: {value} is not a number: give {phrase}"
    if not definition.minimum() <= number <= definition.maximum():
        return f"{definition.name()}: {number:g} is out of range: give {phrase}"
    return ""


def raster_problem(definition, value):
    """Why QGIS cannot load `value` of the raster parameter `definition` (a missing file, a SPOT DIMAP product
    without its raster, a file GDAL does not read as a raster), or '' where it names no local file."""
    path = _file_path(value if isinstance(value, str) else "")
    if path is None:
        return ""
    try:
        sensors.check_image(path)
    except PushbroomError as exc:
        return f"{definition.name()}: {exc}"
    return (
        f"{definition.name()}: {path} is not a raster GDAL reads (a damaged or unsupported file?); give an "
        "image or DEM file"
    )


class _CheckFailedError(Exception):
    """QGIS's own parameter check failed (PushbroomAlgorithm.checkParameterValues)."""


class PushbroomAlgorithm(QgsProcessingAlgorithm):
    """Subclasses set NAME, DISPLAY_NAME, GROUP_ID (a key of GROUPS), a class constant per parameter and output
    key (`BLOCK = "BLOCK"`, as QGIS's script template does) and implement `execute`: read
    the parameters, call the step's one engine entry point, load its outputs. The help is the step's page,
    docs/steps/<NAME>.md: its first paragraph is the short help, helpUrl opens the whole page."""

    NAME = ""
    DISPLAY_NAME = ""
    GROUP_ID = ""
    #: the file parameter that names a block: its files and images are inputs (Block.files)
    BLOCK_PARAMETER = "BLOCK"
    #: {folder output: the file that marks a folder the step made} of the folder outputs the step replaces as a
    #: whole (destinations.FOLDER); the other folder outputs are written into
    WHOLE_FOLDERS = {}

    def createInstance(self):
        return type(self)()

    def tr(self, text):
        """`text` in the user's language (`translated`). Literal texts are written `translate("Pushbroom", "...")`,
        which pylupdate5 extracts (`make`: i18n/pushbroom.ts)."""
        return translated(text)

    def name(self):
        return self.NAME

    def displayName(self):
        return translated(self.DISPLAY_NAME)

    def group(self):
        return translated(GROUPS[self.GROUP_ID])

    def groupId(self):
        return self.GROUP_ID

    def shortHelpString(self):
        return short_help(self.NAME)

    def helpUrl(self):
        """The step's page in the repository's docs (docs/steps/<name>.md), shipped with the plugin."""
        return QUrl.fromLocalFile(help_page(self.NAME)).toString()

    def addParameter(self, parameter, createOutput=True):
        """QgsProcessingAlgorithm.addParameter, with the parameter's help from the step's page (parameter_help) and
        its range (state_range)."""
        parameter.setHelp(parameter_help(self.NAME).get(parameter.name(), ""))
        return super().addParameter(state_range(parameter), createOutput)

    def checkParameterValues(self, parameters, context):
        """QGIS's check of the parameter values, its failures in Pushbroom's words (module docstring): numbers
        first (number_problem); then QGIS's own check, which loads the layers, with GDAL's lines meanwhile
        held back where it fails (the message below says what is wrong); a raster QGIS cannot load is named
        with why (raster_problem)."""
        for definition in self.parameterDefinitions():
            if isinstance(definition, QgsProcessingParameterNumber):
                problem = number_problem(definition, parameters.get(definition.name()))
                if problem:
                    return False, problem
        try:
            with reported_here():
                ok, message = super().checkParameterValues(parameters, context)
                if not ok:  # QGIS loads the rasters again here: GDAL's lines held back too
                    for definition in self.parameterDefinitions():
                        value = parameters.get(definition.name())
                        if isinstance(
                            definition, QgsProcessingParameterRasterLayer
                        ) and not definition.checkValueIsAcceptable(value, context):
                            message = raster_problem(definition, value) or message
                            break
                    raise _CheckFailedError(message)
        except _CheckFailedError:
            return False, message
        return ok, message

    def addAdvancedParameters(self, parameters):
        """Add `parameters` flagged as advanced (folded away in the dialog)."""
        for parameter in parameters:
            parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(parameter)

    def parameterAsOptionalDouble(self, parameters, key, context):
        """The number of an optional parameter, or None where it is not set."""
        value = parameters.get(key)
        return None if value is None or value == "" else self.parameterAsDouble(parameters, key, context)

    def parameterAsCrsDefinition(self, parameters, key, context):
        """The CRS of a CRS parameter as the engine takes it (authority id, else WKT), or None where unset.
        A text the user gave that is no valid CRS is an InputError (QGIS would treat it as unset)."""
        crs = self.parameterAsCrs(parameters, key, context)
        if crs.isValid():
            return crs.authid() or crs.toWkt(crs.WKT_PREFERRED)
        given = parameters.get(key)
        if isinstance(given, str) and given.strip():
            definition = self.parameterDefinition(key)
            raise InputError(
                f"{definition.description() if definition else key}: {given.strip()[:200]!r} is not a "
                "coordinate reference system QGIS knows; give an EPSG code such as EPSG:32632, or WKT, "
                "or leave it empty for the default"
            )
        return None

    def icon(self):
        return QIcon(resource_path("icons", "pushbroom.svg"))

    @staticmethod
    def given(outputs):
        """The outputs dict without the optional outputs that were not made (value None or empty)."""
        return {key: value for key, value in outputs.items() if value is not None and value != ""}

    def inputs(self, parameters, context) -> list:
        """destinations.Input of every file and folder the step reads: what its file, layer and multiple-layer
        parameters name and, of a block parameter (BLOCK_PARAMETER), the block's own files and the images it
        refers to (Block.files); each with the files read with it (destinations.files_of)."""
        found = []
        for definition in self.parameterDefinitions():
            name = definition.name()
            if definition.isDestination():
                continue
            if name == self.BLOCK_PARAMETER and isinstance(definition, QgsProcessingParameterFile):
                path = self.parameterAsFile(parameters, name, context)
                named = Block(path).files() if path else {}
            else:
                named = dict.fromkeys(self._read_paths(definition, parameters, context), "")
            for path, part in named.items():
                for file in destinations.files_of(path):
                    with_it = "" if file == path else "a file read with it"
                    found.append(destinations.Input(file, self._label(name), ", ".join(filter(None, (part, with_it)))))
        return found

    def _read_paths(self, definition, parameters, context) -> list:
        """The local files a file, layer or multiple-layer parameter names (none for the other kinds)."""
        name = definition.name()
        if isinstance(definition, QgsProcessingParameterFile):
            paths = [self.parameterAsFile(parameters, name, context)]
        elif isinstance(definition, QgsProcessingParameterRasterLayer):
            paths = [_layer_path(self.parameterAsRasterLayer(parameters, name, context))]
        elif isinstance(definition, (QgsProcessingParameterVectorLayer, QgsProcessingParameterFeatureSource)):
            paths = [_layer_path(self.parameterAsVectorLayer(parameters, name, context))]
        elif isinstance(definition, QgsProcessingParameterMultipleLayers):
            if definition.layerType() == QgsProcessing.TypeFile:
                paths = self.parameterAsFileList(parameters, name, context)
            else:
                paths = [_layer_path(layer) for layer in self.parameterAsLayerList(parameters, name, context)]
        else:
            paths = []
        return [p for p in map(_file_path, paths) if p]

    def destinations(self, parameters, context) -> list:
        """destinations.Destination of every file or folder output that was given, with the extensions its
        writer honours (a file output's file filter, the provider's raster and vector formats), and those of
        `extra_destinations`."""
        found = []
        for definition in self.destinationParameterDefinitions():
            name, kind, extensions, mark = definition.name(), destinations.FILE, (), ""
            if isinstance(definition, QgsProcessingParameterFolderDestination):
                path = self.parameterAsString(parameters, name, context)
                kind = destinations.FOLDER if name in self.WHOLE_FOLDERS else destinations.INTO
                mark = self.WHOLE_FOLDERS.get(name, "")
            elif isinstance(definition, QgsProcessingParameterFileDestination):
                path = self.parameterAsFileOutput(parameters, name, context)
                extensions = filter_extensions(definition.fileFilter())
            elif isinstance(definition, QgsProcessingParameterRasterDestination):
                path = self.parameterAsOutputLayer(parameters, name, context)
                extensions = tuple(definition.supportedOutputRasterLayerExtensions())
            elif isinstance(definition, QgsProcessingParameterVectorDestination):
                path = self.parameterAsOutputLayer(parameters, name, context)
                extensions = tuple(definition.supportedOutputVectorLayerExtensions())
            else:
                continue
            path = _file_path(path)
            if path:
                found.append(destinations.Destination(path, self._label(name), kind, extensions, mark))
        return found + self.extra_destinations(parameters, context)

    def extra_destinations(self, parameters, context) -> list:
        """destinations.Destination of the files the step writes that no parameter names (a file made beside an
        output); none by default."""
        return []

    def _label(self, name: str) -> str:
        """A parameter as messages name it: 'OUTPUT (Point file)' (without a description's own parentheses)."""
        definition = self.parameterDefinition(name)
        description = re.sub(r"\s*\(.*\)\s*$", "", definition.description()) if definition is not None else ""
        return f"{name} ({description})" if description else name

    def check_destinations(self, parameters, context) -> None:
        """destinations.check of the step's outputs against its inputs, before any work (the inputs are not
        looked at where no output is given)."""
        outputs = self.destinations(parameters, context)
        if outputs:
            destinations.check(self.inputs(parameters, context), outputs)

    def processAlgorithm(self, parameters, context, feedback):
        line_buffered_stdout()  # qgis_process's lines leave as they are written
        try:
            self.check_destinations(parameters, context)
            with raster_cache.bounded():  # GDAL's block cache while the step runs
                return self.execute(parameters, context, feedback)
        except PushbroomError as exc:
            _single_error()
            raise QgsProcessingException(str(exc)) from exc

    def execute(self, parameters, context, feedback):
        raise NotImplementedError

    def parameterValues(self, parameters, context, **keys):
        """{name: value} of the plain parameters keys {name: parameter key}, each read by its definition's
        type: boolean, integer, double (None where an optional one is unset), file, enum (the index) or
        string."""
        values = {}
        for name, key in keys.items():
            definition = self.parameterDefinition(key)
            if isinstance(definition, QgsProcessingParameterBoolean):
                values[name] = self.parameterAsBool(parameters, key, context)
            elif isinstance(definition, QgsProcessingParameterNumber):
                if definition.dataType() == QgsProcessingParameterNumber.Integer:
                    values[name] = self.parameterAsInt(parameters, key, context)
                elif definition.flags() & QgsProcessingParameterDefinition.FlagOptional:
                    values[name] = self.parameterAsOptionalDouble(parameters, key, context)
                else:
                    values[name] = self.parameterAsDouble(parameters, key, context)
            elif isinstance(definition, QgsProcessingParameterFile):
                values[name] = self.parameterAsFile(parameters, key, context)
            elif isinstance(definition, QgsProcessingParameterEnum):
                values[name] = self.parameterAsEnum(parameters, key, context)
            else:
                values[name] = self.parameterAsString(parameters, key, context)
        return values


#: labels of the height datums control_points.HEIGHT_TYPES
HEIGHT_LABELS = {
    "ellipsoidal": QT_TRANSLATE_NOOP("Pushbroom", "Ellipsoidal (WGS 84)"),
    "orthometric": QT_TRANSLATE_NOOP("Pushbroom", "Orthometric (EGM96 geoid; needs PROJ's EGM96 grid)"),
}


def cog_parameter(algorithm):
    """The optional advanced boolean COG (its class constant) of an algorithm with raster outputs: write them as
    Cloud-Optimised GeoTIFFs (surface/geotiff.raster_output). Optional, so that the models saved before it validate."""
    parameter = QgsProcessingParameterBoolean(
        algorithm.COG, translate("Pushbroom", "Raster outputs as Cloud-Optimised GeoTIFF (COG)"), False, optional=True
    )
    parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    return parameter


def heights_parameter(key, description):
    """An enum parameter choosing one of control_points.HEIGHT_TYPES (default: ellipsoidal); read it with
    heights_choice."""
    labels = [translated(HEIGHT_LABELS[h]) for h in HEIGHT_TYPES]
    return QgsProcessingParameterEnum(key, description, labels, defaultValue=0)


def heights_choice(algorithm, parameters, key, context):
    """The HEIGHT_TYPES value of a heights_parameter."""
    return HEIGHT_TYPES[algorithm.parameterAsEnum(parameters, key, context)]


#: labels of the execution backends task_runtime.BACKENDS
EXECUTION_LABELS = {
    "threads": QT_TRANSLATE_NOOP("Pushbroom", "Threads in this process"),
    "processes": QT_TRANSLATE_NOOP("Pushbroom", "Local worker processes"),
    "dask": QT_TRANSLATE_NOOP("Pushbroom", "Dask distributed: a local cluster, or the scheduler at the address below"),
}


def execution_parameters(algorithm, workers, optional=False):
    """The advanced parameters EXECUTION, DASK_ADDRESS, DASK_WAIT and WORKERS (default `workers`) of an algorithm
    whose tiles run on execution.run_tasks (its class constants name the four); read them with execution_choice.
    DASK_WAIT is optional, so that the models saved before it still validate; all four where `optional` (an
    algorithm that gained them later: its models saved before still validate)."""
    parameters = [
        QgsProcessingParameterEnum(
            algorithm.EXECUTION,
            translate("Pushbroom", "Execution of the tiles"),
            [translated(EXECUTION_LABELS[b]) for b in BACKENDS],
            defaultValue=0,
        ),
        QgsProcessingParameterString(
            algorithm.DASK_ADDRESS,
            translate("Pushbroom", "Dask scheduler address (tcp:// or tls://host:port; empty: a local cluster)"),
            "",
            optional=True,
        ),
        QgsProcessingParameterNumber(
            algorithm.DASK_WAIT,
            translate("Pushbroom", "Wait for a Dask worker where the cluster has none, or has lost every one (s)"),
            QgsProcessingParameterNumber.Double,
            Execution.worker_wait,
            optional=True,
            minValue=0.0,
        ),
        QgsProcessingParameterNumber(
            algorithm.WORKERS,
            translate(
                "Pushbroom", "Workers (threads, processes or local Dask workers; at most {} per core are used)"
            ).format(WORKERS_PER_CORE),
            QgsProcessingParameterNumber.Integer,
            workers,
            minValue=1,
        ),
    ]
    for parameter in parameters if optional else ():
        parameter.setFlags(parameter.flags() | QgsProcessingParameterDefinition.FlagOptional)
    return parameters


def execution_choice(algorithm, parameters, context):
    """The execution.Execution of an algorithm's execution_parameters, checked (InputError before any work for a
    malformed scheduler address). Its host_events run Qt's event loop while the tiles run, where the algorithm
    runs on the application's main thread (qgis_process): qgis_process cancels the feedback on Ctrl+C only from
    its event loop."""
    values = algorithm.parameterValues(
        parameters,
        context,
        backend=algorithm.EXECUTION,
        address=algorithm.DASK_ADDRESS,
        workers=algorithm.WORKERS,
        worker_wait=algorithm.DASK_WAIT,
    )
    if values["worker_wait"] is None:
        del values["worker_wait"]
    values["backend"] = BACKENDS[values["backend"]]
    values["address"] = values["address"].strip()
    app = QCoreApplication.instance()

    def host_events():
        if app is not None and QThread.currentThread() == app.thread():
            QCoreApplication.processEvents(QEventLoop.ExcludeUserInputEvents)

    return Execution(**values, host_events=host_events).check()


def replace_fewer_parameter(algorithm: QgsProcessingAlgorithm, what: str) -> QgsProcessingParameterBoolean:
    """The boolean REPLACE_FEWER (off; put it among the advanced parameters): store the new `what` even where they
    are far fewer than the block holds, which the engine otherwise refuses (algorithms/block/replacement.py).
    Optional, so that the models saved before it still validate."""
    return QgsProcessingParameterBoolean(
        algorithm.REPLACE_FEWER,
        translate("Pushbroom", "Replace the block's {} even by far fewer (none, or below half)").format(what),
        False,
        optional=True,
    )
