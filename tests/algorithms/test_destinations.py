"""destinations.check: no output over an input, over another output or over something that is not a file,
and no output in a format its name does not say (issue 36). The Processing steps' cases are in
tests/plugin/test_output_paths_alg.py, the property over every algorithm's outputs in
tests/plugin/test_output_paths_property.py."""

import os
import socket

import pytest

from pushbroom.algorithms import destinations
from pushbroom.algorithms.destinations import FILE, FOLDER, INTO, Destination, Input
from pushbroom.algorithms.errors import InputError, PushbroomError, StorageError


@pytest.fixture
def world(tmp_path):
    """An input file, an input folder (like a block's point folder) with a file in it, and their bytes."""
    block = tmp_path / "data" / "block.gpkg"
    block.parent.mkdir()
    block.write_bytes(b"block contents")
    folder = tmp_path / "data" / "block.mass_points.h-1-0123abcd"
    folder.mkdir()
    (folder / "index.json").write_text("{}")
    inputs = [Input(str(block), "BLOCK (Block)"), Input(str(folder), "BLOCK (Block)", "its point folder")]
    return {"block": str(block), "folder": str(folder), "inputs": inputs}


def refused(world, destination, match):
    """check refuses `destination` with a message matching `match`, and the inputs are as they were."""
    with pytest.raises(PushbroomError, match=match) as info:
        destinations.check(world["inputs"], [destination])
    assert open(world["block"], "rb").read() == b"block contents"
    assert os.listdir(world["folder"]) == ["index.json"]
    return str(info.value)


def test_an_output_that_is_an_input_by_any_name_is_refused(world, tmp_path):
    block = world["block"]
    os.symlink(block, tmp_path / "link.csv")
    os.link(block, tmp_path / "hard.csv")
    os.symlink(os.path.dirname(block), tmp_path / "linked-folder")
    text = refused(world, Destination(block, "OUTPUT (Point file)"), "would overwrite the input BLOCK")
    assert f"both name {block}" in text and "nothing was written" in text
    relative = os.path.relpath(block)
    refused(world, Destination(relative, "OUTPUT (Point file)"), "would overwrite the input BLOCK")
    refused(world, Destination(str(tmp_path / "link.csv"), "OUTPUT (Point file)"), "through a symbolic link")
    refused(
        world,
        Destination(str(tmp_path / "linked-folder" / "block.gpkg"), "OUTPUT (Point file)"),
        "through a symbolic link",
    )
    refused(world, Destination(str(tmp_path / "hard.csv"), "OUTPUT (Point file)"), "is a hard link of")
    # a shapefile's companion is written too: x.dbf beside x.shp
    os.link(block, tmp_path / "x.dbf")
    refused(world, Destination(str(tmp_path / "x.shp"), "RESIDUALS (Residual vectors)"), "is a hard link of")


def test_an_output_inside_an_input_folder_is_refused(world):
    refused(
        world,
        Destination(os.path.join(world["folder"], "p.csv"), "OUTPUT (Point file)"),
        "lies inside the input BLOCK .*its point folder",
    )
    refused(world, Destination(world["folder"], "OUTPUT_FOLDER (Output folder)", INTO), "would overwrite the input")
    refused(
        world,
        Destination(os.path.join(world["folder"], "rpc"), "OUTPUT_FOLDER (Output folder)", INTO),
        "lies inside the input",
    )


def test_a_folder_replaced_as_a_whole_holds_neither_an_input_nor_foreign_files(world, tmp_path):
    data = os.path.dirname(world["block"])
    refused(
        world,
        Destination(data, "OUTPUT (Output folder)", FOLDER, mark="truth.json"),
        "replaced as a whole, and it holds the input BLOCK",
    )
    own = tmp_path / "own"
    own.mkdir()
    (own / "notes.txt").write_text("the user's")
    refused(
        world,
        Destination(str(own), "OUTPUT (Output folder)", FOLDER, mark="truth.json"),
        "holds files this step did not make",
    )
    assert (own / "notes.txt").read_text() == "the user's"
    (own / "truth.json").write_text("{}")  # a folder the step made: it may replace it
    destinations.check(world["inputs"], [Destination(str(own), "OUTPUT (Output folder)", FOLDER, mark="truth.json")])
    destinations.check(world["inputs"], [Destination(str(tmp_path / "new"), "OUTPUT", FOLDER, mark="truth.json")])


def test_two_outputs_that_are_one_file_are_refused(world, tmp_path):
    a = Destination(str(tmp_path / "dem.tif"), "OUTPUT (DEM)")
    for other in (str(tmp_path / "dem.tif"), str(tmp_path / "." / "dem.tif")):
        with pytest.raises(InputError, match="the outputs OUTPUT .DEM. and PRECISION .Precision raster. are the same"):
            destinations.check(world["inputs"], [a, Destination(other, "PRECISION (Precision raster)")])
    with pytest.raises(InputError, match="lies inside the output folder OUTPUT"):
        destinations.check(
            [],
            [Destination(str(tmp_path / "s"), "OUTPUT", FOLDER), Destination(str(tmp_path / "s" / "r.html"), "REPORT")],
        )
    assert not (tmp_path / "dem.tif").exists()


def test_what_is_not_a_regular_file_is_never_replaced(world, tmp_path):
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(tmp_path / "socket.csv"))
    (tmp_path / "folder.csv").mkdir()
    try:
        for path, kind in [(fifo, "a FIFO"), (tmp_path / "socket.csv", "a socket"), ("/dev/null", "a device")]:
            with pytest.raises(StorageError, match=f"it is {kind}, not a regular file, and is never replaced"):
                destinations.check(world["inputs"], [Destination(str(path), "OUTPUT (Point file)", FILE, ("csv",))])
        with pytest.raises(StorageError, match="a folder of that name is in the way"):
            destinations.check(world["inputs"], [Destination(str(tmp_path / "folder.csv"), "OUTPUT")])
        with pytest.raises(StorageError, match="a FIFO has that name, and only a folder is replaced by the folder"):
            destinations.check(world["inputs"], [Destination(str(fifo), "OUTPUT (Output folder)", FOLDER)])
    finally:
        server.close()
    assert fifo.is_fifo() and (tmp_path / "socket.csv").is_socket() and os.path.exists("/dev/null")


def test_an_extension_the_writer_cannot_honour_is_refused(world, tmp_path):
    for name in ("e.shp", "e.xlsx", "e.gpkg", "e"):
        text = refused(
            world, Destination(str(tmp_path / name), "OUTPUT (Point file)", FILE, ("csv",)), "is written as .csv only"
        )
        assert "Give a name ending in .csv" in text
        assert not (tmp_path / name).exists()
    refused(
        world,
        Destination(str(tmp_path / "d.las"), "OUTPUT (DEM)", FILE, ("tif", "tiff")),
        r"written as \.tif or \.tiff only, and its name ends in '\.las'",
    )
    destinations.check(world["inputs"], [Destination(str(tmp_path / "E.CSV"), "OUTPUT", FILE, ("csv",))])


def test_outputs_beside_inputs_and_a_folder_written_into_that_holds_them_pass(world, tmp_path):
    data = os.path.dirname(world["block"])
    destinations.check(
        world["inputs"],
        [
            Destination(os.path.join(data, "points.csv"), "OUTPUT (Point file)", FILE, ("csv",)),
            Destination(data, "OUTPUT_FOLDER (Output folder)", INTO),  # fitrpc's files beside the block
            Destination(str(tmp_path / "new" / "report.html"), "REPORT (Report)", FILE, ("html",)),
        ],
    )
    assert sorted(os.listdir(data)) == ["block.gpkg", "block.mass_points.h-1-0123abcd"]  # the probes are gone


def test_the_files_of_a_dimap_image_include_its_metadata(small_scene):
    image = small_scene["images"]["HRG"]
    files = destinations.files_of(image["imagery"])
    assert files[0] == image["imagery"] and image["metadata"] in files
    assert destinations.files_of("/nonexistent/x.las") == ["/nonexistent/x.las"]
