"""pushbroom:matchpoints on a block of one image (issue 19): the message says that matching needs two or
three images and the block has one (before: "name the 2 or 3 to match in the Images parameter", which one
image cannot do)."""

import re

import pytest
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.image_order import combination_order

ONE_IMAGE = (
    "matching needs two or three images of the same ground, and the block has one image (HRG): create a "
    "block with the stereo pair or triplet (pushbroom:createblock with all its images) and match that"
)


def test_combination_order_of_one_or_no_image():
    for text in ("", "all", "HRG", "HRG,HRS1"):  # whatever the Images parameter says
        with pytest.raises(InputError, match=f"^{re.escape(ONE_IMAGE)}$"):
            combination_order([{"name": "HRG"}], text)
    with pytest.raises(InputError, match="the block has no image:"):
        combination_order([], "")


def test_matchpoints_on_a_one_image_block(pushbroom_provider, small_scene, tmp_path):
    path = str(tmp_path / "one.gpkg")
    Block.create(path, Block.open_images([small_scene["images"]["HRG"]["imagery"]]), height=400.0)
    message = None
    try:
        processing.run("pushbroom:matchpoints", {"BLOCK": path}, context=QgsProcessingContext())
    except QgsProcessingException as exc:  # only the text is kept (no traceback holding QGIS objects)
        message = str(exc)
    assert message is not None and message.endswith(ONE_IMAGE)  # refused, with the reason and the remedy
    assert "Images parameter" not in message  # not the advice one image cannot follow
