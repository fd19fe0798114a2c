"""One block identity (issue 36): a block opened through a symbolic link in another folder keeps its point
folders beside the real file, recorded under its real name, so every step sees the same points through the
link and through the real path; Block.files lists everything of the block no output may overwrite."""

import os

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.block.schema import create_schema
from tests.helpers.points_synthetic import synthetic


def same_points(a, b):
    return a.points.tobytes() == b.points.tobytes() and a.observations.tobytes() == b.observations.tobytes()


def test_points_stored_through_a_link_are_seen_through_both_paths(tmp_path):
    (tmp_path / "data").mkdir()
    (tmp_path / "sl").mkdir()
    real = tmp_path / "data" / "b.gpkg"
    create_schema(real).Destroy()
    link = tmp_path / "sl" / "link.gpkg"
    link.symlink_to(real)
    mass, tie = synthetic(500), synthetic(40)
    folder = Block(link).store_points(mass)  # matchpoints BLOCK=sl/link.gpkg
    Block(real).store_points(tie, "tie_points")  # selecttiepoints by the real path
    assert os.path.dirname(folder) == str(tmp_path / "data") and os.path.basename(folder).startswith("b.mass_points.")
    assert os.listdir(tmp_path / "sl") == ["link.gpkg"]  # nothing beside the link
    for path in (real, link):
        assert same_points(Block(path).points(), mass) and same_points(Block(path).points("tie_points"), tie)
    assert Block(link).path == Block(real).path == str(real)
    # a second store through the link replaces the first: one point folder per kind, beside the real file
    Block(link).store_points(mass.subset([1, 2, 3]), replace_fewer=True)  # far fewer: on purpose
    assert len(Block(real).points()) == 3
    assert sorted(name.split(".")[1] for name in os.listdir(tmp_path / "data") if name != "b.gpkg") == [
        "mass_points",
        "tie_points",
    ]


def test_block_files_are_its_geopackage_journals_point_folders_and_images(tmp_path, small_scene_block):
    real = tmp_path / "b.gpkg"
    real.write_bytes(small_scene_block[0].read_bytes())
    Block(real).store_points(synthetic(10))
    files = Block(real).files()
    images = Block(real).images()
    folders = [p for p in files if os.path.isdir(p)]
    assert [os.path.basename(p).split(".")[1] for p in folders] == ["mass_points"]
    assert {str(real) + s for s in ("", "-journal", "-wal", "-shm")} <= set(files)
    for row in images:
        assert files[os.path.realpath(row["image_path"])] == f"the image {row['name']}"
        assert files[os.path.realpath(row["orientation_path"])] == f"the orientation file of image {row['name']}"
    assert len(files) == 4 + len(folders) + 2 * len(images)
