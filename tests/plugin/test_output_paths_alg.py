"""Issue 36's data-loss cases of output paths, each exactly as the hostile round ran it, in-process: an output
that is the step's own input, a block through a symbolic link, an output in a format its name does not say,
a device node as output. Each is refused before any work, with a message that names both parameters, and
leaves every input byte-identical."""

import os
import shutil
import stat

import pytest
from qgis import processing
from qgis.core import QgsProcessingException

from pushbroom.algorithms.block import Block
from tests.helpers import output_world
from tests.helpers.fingerprint import fingerprint


@pytest.fixture(scope="module")
def world(small_scene, tmp_path_factory):
    return output_world.build(tmp_path_factory.mktemp("inputs"), small_scene)


def refused(algorithm, parameters, match, world):
    """processing.run refuses with a message matching `match`, and no input changed."""
    before = fingerprint(world["folder"])
    with pytest.raises(QgsProcessingException, match=match) as info:
        processing.run(algorithm, parameters)
    assert fingerprint(world["folder"]) == before
    return str(info.value)


def overwrites(output, source):
    """The refusal of an output named as one of the inputs: 'the output OUTPUT (DEM) would overwrite the input ...'."""
    return rf"the output {output} would overwrite the input {source}: both name"


def ortho(world, output):
    return {"BLOCK": world["block"], "IMAGE_NAME": "HRG", "DEM": world["dsm"], "OUTPUT": output}


#: the row "OUTPUT is the step's own input": {case: (algorithm, parameters of the world, the refusal)}
OWN_INPUT = {
    "intersectpoints OUTPUT=block": (
        "pushbroom:intersectpoints",
        lambda w: {"BLOCK": w["block"], "OUTPUT": w["block"]},
        overwrites("OUTPUT .Point cloud.", "BLOCK .Block."),
    ),
    # the block is no input of interpolatedem: its name is refused as a GeoTIFF's
    "interpolatedem OUTPUT=block": (
        "pushbroom:interpolatedem",
        lambda w: {"INPUT": w["las"], "OUTPUT": w["block"]},
        r"the output OUTPUT .DEM. .*block\.gpkg is written as \.tif or \.tiff only",
    ),
    "orthorectify OUTPUT=block": (
        "pushbroom:orthorectify",
        lambda w: ortho(w, w["block"]),
        overwrites("OUTPUT .Orthoimage.", "BLOCK .Block."),
    ),
    "exportpoints OUTPUT=block": (
        "pushbroom:exportpoints",
        lambda w: {"BLOCK": w["block"], "OUTPUT": w["block"]},
        overwrites("OUTPUT .Point file.", "BLOCK .Block."),
    ),
    "bundleadjust REPORT=block": (
        "pushbroom:bundleadjust",
        lambda w: {"BLOCK": w["block"], "REPORT": w["block"]},
        overwrites("REPORT .Report.", "BLOCK .Block."),
    ),
    "orthorectify OUTPUT=its DEM": (
        "pushbroom:orthorectify",
        lambda w: ortho(w, w["dsm"]),
        overwrites("OUTPUT .Orthoimage.", "DEM .DEM."),
    ),
    "orthorectify OUTPUT=an image of its block": (
        "pushbroom:orthorectify",
        lambda w: ortho(w, w["images"][1]),
        overwrites("OUTPUT .Orthoimage.", "BLOCK .Block., the image HRS1"),
    ),
    "interpolatedem OUTPUT=its LAS": (
        "pushbroom:interpolatedem",
        lambda w: {"INPUT": w["las"], "OUTPUT": w["las"]},
        overwrites("OUTPUT .DEM.", "INPUT .Point cloud."),
    ),
}


@pytest.mark.parametrize("case", sorted(OWN_INPUT))
def test_an_output_that_is_the_steps_own_input_is_refused(pushbroom_provider, world, case):
    algorithm, parameters, match = OWN_INPUT[case]
    assert "nothing was written" in refused(algorithm, parameters(world), match, world)


def test_an_output_through_a_link_to_an_input_is_refused(pushbroom_provider, world, tmp_path):
    (tmp_path / "dem.tif").symlink_to(world["dsm"])
    os.link(world["block"], tmp_path / "points.csv")
    refused("pushbroom:orthorectify", ortho(world, str(tmp_path / "dem.tif")), "through a symbolic link", world)
    refused(
        "pushbroom:exportpoints",
        {"BLOCK": world["block"], "OUTPUT": str(tmp_path / "points.csv")},
        "is a hard link of",
        world,
    )


def test_a_block_through_a_link_in_another_folder_is_one_block(pushbroom_provider, world, tmp_path):
    """selecttiepoints BLOCK=sl/link.gpkg: the tie points are stored beside the real block, under its name, and
    seen through its real path; the BLOCK output is the path the user gave."""
    data = tmp_path / "data"  # a copy of the world's block: this step changes it
    data.mkdir()
    for name in os.listdir(world["folder"]):
        if name.startswith("block."):
            source = os.path.join(world["folder"], name)
            (shutil.copytree if os.path.isdir(source) else shutil.copy)(source, data / name)
    (tmp_path / "sl").mkdir()
    link = tmp_path / "sl" / "link.gpkg"
    link.symlink_to(data / "block.gpkg")
    result = processing.run("pushbroom:selecttiepoints", {"BLOCK": str(link), "CELL": 50, "MIN_GROUP": 1})
    assert result["BLOCK"] == str(link)
    assert os.listdir(tmp_path / "sl") == ["link.gpkg"]
    assert os.path.dirname(result["TIE_POINTS_FILE"]) == str(data)
    by_link, by_path = Block(link).points("tie_points"), Block(data / "block.gpkg").points("tie_points")
    assert len(by_path) > 0 and by_link.points.tobytes() == by_path.points.tobytes()
    assert len(Block(data / "block.gpkg").points()) == 60  # the mass points, seen through the real path


@pytest.mark.parametrize("name", ["e.shp", "e.xlsx", "e.gpkg"])
def test_exportpoints_writes_csv_under_a_csv_name_only(pushbroom_provider, world, tmp_path, name):
    text = refused(
        "pushbroom:exportpoints",
        {"BLOCK": world["block"], "OUTPUT": str(tmp_path / name)},
        r"the output OUTPUT .Point file. .* is written as \.csv only",
        world,
    )
    assert "Give a name ending in .csv" in text and os.listdir(tmp_path) == []


def test_a_matching_summary_is_a_csv(pushbroom_provider, world, tmp_path):
    refused(
        "pushbroom:matchpoints",
        {"BLOCK": world["block"], "SUMMARY": str(tmp_path / "x.gpkg")},
        r"the output SUMMARY .Summary per point group. .* is written as \.csv only",
        world,
    )
    assert os.listdir(tmp_path) == []


def test_a_device_node_as_output_is_never_replaced(pushbroom_provider, world, tmp_path):
    """As root, OUTPUT=/dev/full replaced the device node with a file; now it is refused whoever runs it."""
    os.mkfifo(tmp_path / "fifo.csv")
    refused(
        "pushbroom:exportpoints",
        {"BLOCK": world["block"], "OUTPUT": "/dev/full"},
        "it is a device, not a regular file, and is never replaced",
        world,
    )
    refused(
        "pushbroom:exportpoints",
        {"BLOCK": world["block"], "OUTPUT": str(tmp_path / "fifo.csv")},
        "it is a FIFO, not a regular file",
        world,
    )
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode) and stat.S_ISFIFO(os.stat(tmp_path / "fifo.csv").st_mode)
