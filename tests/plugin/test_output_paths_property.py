"""The property over the output paths of every algorithm (issue 36): whatever its outputs are drawn among (each
input file, a symbolic or a hard link to one, the block's point folders and a file inside one, fresh paths, a
FIFO, a folder, a device node), the check before the work refuses exactly where an output resolves to an
input or lies inside an input folder, resolves to another output, or is not what its writer replaces: computed
here on its own, with os.stat. A drawn run refused leaves every input byte-identical, and so does a drawn run of
exportpoints it accepts."""

import itertools
import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from qgis import processing
from qgis.core import (
    QgsApplication,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingParameterDefinition,
    QgsProcessingParameterFileDestination,
    QgsProcessingParameterFolderDestination,
    QgsProcessingParameterRasterDestination,
)

from pushbroom.algorithms.errors import PushbroomError
from pushbroom.plugin.algorithms.base import filter_extensions
from tests.helpers import output_world
from tests.helpers.fingerprint import fingerprint

#: the input parameters of each algorithm, in the world of output_world.build
INPUTS = {
    "simulatescene": lambda w: {"LOOK_TABLE": w["metadata"][0], "ORTHOIMAGE": w["dtm"]},
    "createblock": lambda w: {"IMAGES": w["images"], "DEM": w["dsm"]},
    "matchpoints": lambda w: {"BLOCK": w["block"]},
    "selecttiepoints": lambda w: {"BLOCK": w["block"]},
    "importpoints": lambda w: {"BLOCK": w["block"], "INPUT": w["points"]},
    "exportpoints": lambda w: {"BLOCK": w["block"]},
    "bundleadjust": lambda w: {"BLOCK": w["block"], "REFERENCE_DEM": w["dsm"]},
    "intersectpoints": lambda w: {"BLOCK": w["block"]},
    "interpolatedem": lambda w: {"INPUT": w["las"]},
    "orthorectify": lambda w: {"BLOCK": w["block"], "IMAGE_NAME": "HRG", "DEM": w["dsm"]},
    "coregisterdem": lambda w: {"DEM": w["dsm"], "REFERENCE": w["dtm"]},
    "mergedems": lambda w: {"DEMS": [w["dsm"], w["dtm"]]},
    "extractdtm": lambda w: {"DSM": w["dsm"]},
    "assessaccuracy": lambda w: {"REFERENCE": w["dsm"], "POINTS": w["las"], "DEM": w["dtm"]},
    "fitrpc": lambda w: {"BLOCK": w["block"]},
}
#: the folder outputs replaced as a whole, and the file that marks a folder their step made
WHOLE = {("simulatescene", "OUTPUT"): os.path.join("truth", "truth.json"), ("intersectpoints", "EPT"): "ept.json"}
#: the algorithms whose drawn runs that the check accepts are run (fast, and they do not change their inputs)
RUN_ACCEPTED = {"exportpoints"}


@pytest.fixture(scope="module")
def world(small_scene, tmp_path_factory):
    w = output_world.build(tmp_path_factory.mktemp("inputs"), small_scene)
    w["metadata"] = [os.path.join(os.path.dirname(i), "METADATA.DIM") for i in w["images"]]
    w["points"] = small_scene["points"]
    return w


def algorithm(name):
    return QgsApplication.processingRegistry().createAlgorithmById(f"pushbroom:{name}")


def test_every_algorithm_is_in_the_property(pushbroom_provider):
    assert {a.name() for a in pushbroom_provider.algorithms()} == set(INPUTS)


def input_files(world, parameters):
    """Every file the inputs consist of, by this test's knowledge of the formats: a block's GeoPackage, its
    SQLite journals, its point folders, its images; a DIMAP image's raster, its GDAL side file and METADATA.DIM;
    a raster and its GDAL side file."""

    def image(raster):
        return [raster, os.path.join(os.path.dirname(raster), "METADATA.DIM"), raster + ".aux.xml"]

    files = []
    for key, value in parameters.items():
        if key == "BLOCK":
            folder = os.path.dirname(value)
            files += [value + s for s in ("", "-journal", "-wal", "-shm")]
            files += [
                os.path.join(folder, n)
                for n in os.listdir(folder)
                if n.startswith(("block.mass_points.", "block.tie_points."))
            ]
            files += [f for i in world["images"] for f in image(i)]
        elif key == "IMAGES":
            files += [f for i in value for f in image(i)]
        elif key == "LOOK_TABLE":
            files += [value, os.path.join(os.path.dirname(value), "IMAGERY.TIF")]
        elif isinstance(value, list):  # a multiple-layer parameter: rasters
            files += [f for v in value for f in (v, v + ".aux.xml")]
        elif key != "IMAGE_NAME":
            files += [value, value + ".aux.xml"]
    return [f for f in files if os.path.exists(f) or f.startswith(world["block"])]


def identity(path):
    """(device, inode) of what `path` leads to, or its real path where there is nothing."""
    try:
        st_ = os.stat(path)
    except OSError:
        return os.path.realpath(path)
    return st_.st_dev, st_.st_ino


def below(path, folder):
    return os.path.realpath(path).startswith(os.path.realpath(folder) + os.sep)


def expected_refusal(outputs, inputs):
    """Whether the outputs {name: (path, kind, mark)} must be refused, for the inputs (module docstring)."""
    same = {identity(p) for p in inputs} | {os.path.realpath(p) for p in inputs}
    folders = [p for p in inputs if os.path.isdir(p)]
    for path, kind, mark in outputs.values():
        if identity(path) in same or os.path.realpath(path) in same or any(below(path, f) for f in folders):
            return True
        if kind == "whole" and (
            any(below(p, path) for p in inputs)
            or (os.path.isdir(path) and os.listdir(path) and not os.path.isfile(os.path.join(path, mark)))
        ):
            return True
        if os.path.exists(path) and (
            os.path.isdir(path) != (kind != "file") or not (os.path.isdir(path) or os.path.isfile(path))
        ):
            return True
    for (a, ka, _), (b, kb, _) in itertools.combinations(outputs.values(), 2):
        if identity(a) == identity(b) or os.path.realpath(a) == os.path.realpath(b):
            return True
        if (ka == "whole" and below(b, a)) or (kb == "whole" and below(a, b)):
            return True
    return False


def extension(definition):
    if isinstance(definition, QgsProcessingParameterFileDestination):
        return filter_extensions(definition.fileFilter())[0]
    if isinstance(definition, QgsProcessingParameterRasterDestination):
        return definition.supportedOutputRasterLayerExtensions()[0]
    return definition.supportedOutputVectorLayerExtensions()[0]


def draw_output(data, world, inputs, case, name, definition, kind):
    """Draw and make an output path of parameter `name` in the example's folder `case` (module docstring)."""
    points = [p for p in inputs if os.path.isdir(p)]
    in_points = ["point folder", "in point folder"] if points else []
    unset = ["unset"] if definition.flags() & QgsProcessingParameterDefinition.FlagOptional else []
    if kind == "file":
        ext = extension(definition)
        hazards = ["input", "symlink", "hardlink", *in_points, "shared", "fifo", "folder", "device"]
        choice = data.draw(st.sampled_from(hazards + ["fresh", *unset] * 6), label=name)
        path = {
            "point folder": points and points[0],
            "in point folder": points and os.path.join(points[0], f"{name}.{ext}"),
            "shared": os.path.join(case, f"shared.{ext}"),  # another output may choose it too
            "fifo": os.path.join(case, f"fifo-{name}.{ext}"),
            "folder": os.path.join(case, f"folder-{name}.{ext}"),
            "device": "/dev/null",
        }.get(choice, os.path.join(case, f"{choice}-{name}.{ext}"))
    else:
        hazards = ["input", "symlink", *in_points[:1], "linked world", "foreign", "fifo"]
        choice = data.draw(st.sampled_from(hazards + ["fresh", *unset, "empty", "made", "world"] * 2), label=name)
        path = {"point folder": points and points[0], "world": world["folder"]}.get(
            choice, os.path.join(case, f"{choice.replace(' ', '-')}-{name}")
        )
    source = (
        data.draw(st.sampled_from(inputs), label=f"{name} input")
        if choice in ("input", "symlink", "hardlink")
        else None
    )
    if choice == "unset":
        return None
    if choice == "input":
        return source
    if choice == "symlink" or (choice == "hardlink" and not os.path.isfile(source)):  # no hard link of those
        os.symlink(source, path)
    elif choice == "hardlink":
        os.link(source, path)
    elif choice == "fifo":
        os.mkfifo(path)
    elif choice in ("folder", "empty"):
        os.mkdir(path)
    elif choice == "linked world":
        os.symlink(world["folder"], path)
    elif choice in ("foreign", "made"):
        os.makedirs(os.path.join(path, "truth"))
        with open(
            os.path.join(path, "truth", "truth.json") if choice == "made" else os.path.join(path, "notes.txt"), "w"
        ) as f:
            f.write("{}")
    return path


EXAMPLES = itertools.count()


@pytest.mark.parametrize("name", sorted(n for n in INPUTS if n not in ("selecttiepoints", "importpoints")))
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_outputs_are_refused_exactly_where_they_would_damage_something(pushbroom_provider, world, tmp_path, name, data):
    alg = algorithm(name)
    parameters = INPUTS[name](world)
    inputs = input_files(world, parameters)
    case = os.path.join(tmp_path, f"example-{next(EXAMPLES)}")
    os.mkdir(case)
    outputs = {}
    for definition in alg.destinationParameterDefinitions():
        key = definition.name()
        kind = (
            ("whole" if (name, key) in WHOLE else "into")
            if isinstance(definition, QgsProcessingParameterFolderDestination)
            else "file"
        )
        path = draw_output(data, world, inputs, case, key, definition, kind)
        if path is not None:
            parameters[key] = path
            outputs[key] = (path, kind, WHOLE.get((name, key), ""))
    expected = expected_refusal(outputs, inputs)
    try:
        alg.check_destinations(parameters, QgsProcessingContext())
        refused = False
    except PushbroomError:
        refused = True
    assert refused == expected, outputs
    if (refused or name in RUN_ACCEPTED) and data.draw(st.booleans(), label="run"):
        before = fingerprint(world["folder"])
        if refused:
            with pytest.raises(QgsProcessingException):
                processing.run(f"pushbroom:{name}", parameters)
        else:
            processing.run(f"pushbroom:{name}", parameters)
        assert fingerprint(world["folder"]) == before
