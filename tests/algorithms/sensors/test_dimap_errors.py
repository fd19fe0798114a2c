"""Bad DIMAP input raises MetadataError with a message that says what is wrong, never a bare
KeyError/ValueError/IndexError; mutated documents give MetadataError or a usable model."""

import copy
import re
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from osgeo import gdal

from pushbroom.algorithms.errors import MetadataError
from pushbroom.algorithms.sensors.dimap import read_dimap
from pushbroom.algorithms.sensors.dimap_writer import write_dimap
from pushbroom.algorithms.sensors.spot import SpotModel
from tests.helpers.spot_synthetic import synthetic_orientation


def dimap_text(mission):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "METADATA.DIM"
        write_dimap(path, synthetic_orientation(mission, ncols=40))
        return path.read_text()


TEXTS = {5: dimap_text(5), 2: dimap_text(2)}


def read_text(text, tmp_path, image=None):
    path = tmp_path / "METADATA.DIM"
    path.write_text(text)
    return read_dimap(path, image=image)


def replace_first(text, tag, value):
    return re.sub(rf"<{tag}>[^<]*</{tag}>", f"<{tag}>{value}</{tag}>", text, count=1)


def test_written_synthetic_documents_read_back(tmp_path):
    for mission, text in TEXTS.items():
        assert read_text(text, tmp_path).mission == mission


@pytest.mark.parametrize("mission", [5, 2])
def test_truncated_xml(mission, tmp_path):
    with pytest.raises(MetadataError, match="not well-formed XML.*truncated"):
        read_text(TEXTS[mission][: len(TEXTS[mission]) // 2], tmp_path)


def test_not_a_dimap_document(tmp_path):
    with pytest.raises(MetadataError, match="not <Dimap_Document>"):
        read_text("<?xml version='1.0'?><Isd></Isd>", tmp_path)


def test_missing_file(tmp_path):
    with pytest.raises(MetadataError, match="cannot read"):
        read_dimap(tmp_path / "nothing" / "METADATA.DIM")


@pytest.mark.parametrize(
    "mission, edit, message",
    [
        (5, lambda t: re.sub(r"<Points>.*</Points>", "", t, flags=re.S), "Ephemeris/Points/Point"),
        (5, lambda t: re.sub(r"(<Point>.*?</Point>\s*){8}", "", t, count=1, flags=re.S), "3 ephemeris samples"),
        (
            5,
            lambda t: replace_first(t, "SCENE_CENTER_TIME", "2005-03-13T05:31:00.250000"),
            "do not cover the acquisition",
        ),
        (
            5,
            lambda t: re.sub(r"<Look_Angles>\s*<DETECTOR_ID>40</DETECTOR_ID>.*?</Look_Angles>", "", t, flags=re.S),
            "39 detectors .* NCOLS = 40; SPOT 5 needs one per detector",
        ),
        (2, lambda t: replace_first(t, "DETECTOR_ID", "2"), "at least the first and last"),
        (
            5,
            lambda t: t.replace(
                "<Metadata_Id>",
                "<Metadata_Identification><METADATA_FORMAT version='2.0'>DIMAP"
                "</METADATA_FORMAT></Metadata_Identification><Metadata_Id>",
            ),
            "DIMAP v2 document .* open the image .* or its RPC file",
        ),
    ],
    ids=["no ephemeris", "3 ephemeris points", "ephemeris too short", "39 look angles", "spot2 look table", "dimap v2"],
)
def test_document_edits(mission, edit, message, tmp_path):
    with pytest.raises(MetadataError, match=message):
        read_text(edit(TEXTS[mission]), tmp_path)


@pytest.mark.parametrize(
    "tag, value, message",
    [
        ("MISSION_INDEX", "7", "MISSION_INDEX 7 is not SPOT 1 to 5"),
        ("MISSION", "LANDSAT", "not SPOT"),
        ("INSTRUMENT", "XYZ", "instrument 'XYZ' does not fly on SPOT 5"),
        ("PSI_Y", "nan", "PSI_Y.*'nan' is not a finite number"),
        ("X", "NaN", "X.*is not a finite number"),
        ("YAW", "1.5e-3x", "YAW.*is not a finite number"),
        ("TIME", "yesterday", "TIME.*not an ISO UTC date-time"),
        ("NCOLS", "0", "is not the size of a SPOT scene"),
        ("NROWS", "12.5", "not an integer"),
        ("LINE_PERIOD", "-1e-3", "LINE_PERIOD"),
        ("PITCH", "3.0", "degrees instead of radians"),
        ("SCENE_CENTER_TIME", "", "SCENE_CENTER_TIME> is empty"),
    ],
)
def test_bad_values(tag, value, message, tmp_path):
    with pytest.raises(MetadataError, match=message):
        read_text(replace_first(TEXTS[5], tag, value), tmp_path)


def test_positions_in_kilometres_are_refused(tmp_path):
    text = re.sub(r"(<Location>\s*<X>)([^<]*)", lambda m: m.group(1) + repr(float(m.group(2)) / 1e3), TEXTS[5])
    with pytest.raises(MetadataError, match="not ECEF metres"):
        read_text(text, tmp_path)


def test_image_size_must_match(tmp_path):
    gdal.UseExceptions()
    gdal.GetDriverByName("GTiff").Create(str(tmp_path / "IMAGERY.TIF"), 200, 300, 1, gdal.GDT_Byte)
    with pytest.raises(MetadataError, match="40 x 200 but the image .* has 200 x 300 pixels"):
        read_text(TEXTS[5], tmp_path, image=tmp_path / "IMAGERY.TIF")
    with pytest.raises(MetadataError, match="cannot open the image"):
        read_text(TEXTS[5], tmp_path, image=tmp_path / "missing.tif")


GARBAGE = st.sampled_from(
    [
        "nan",
        "inf",
        "-inf",
        "",
        "x",
        "1e999",
        "-1",
        "0",
        "1e30",
        "3000000",
        "2005-03-13",
        "1.5.2",
        "+",
        "  7 ",
        "0x10",
        "2005-03-13T05:21:00.5",
    ]
)
TREES = {mission: ET.fromstring(text) for mission, text in TEXTS.items()}


@st.composite
def mutated(draw):
    """A synthetic DIMAP with a few random element edits (delete, garbage text, swapped tags) and
    sometimes truncated text. Elements are drawn by tag name first, so rare tags are hit too."""
    root = copy.deepcopy(TREES[draw(st.sampled_from(sorted(TREES)))])
    for _ in range(draw(st.integers(1, 3))):
        parents = {child: parent for parent in root.iter() for child in parent}
        by_tag = {}
        for e in parents:
            by_tag.setdefault(e.tag, []).append(e)
        pick = lambda: draw(st.sampled_from(by_tag[draw(st.sampled_from(sorted(by_tag)))]))
        kind = draw(st.sampled_from(["delete", "garbage", "garbage", "swap"]))
        element = pick()
        if kind == "delete":
            parents[element].remove(element)
        elif kind == "garbage":
            element.text = draw(GARBAGE)
        else:
            other = pick()
            element.tag, other.tag = other.tag, element.tag
    text = ET.tostring(root, encoding="unicode")
    return text[: draw(st.integers(0, len(text)))] if draw(st.integers(0, 9)) == 0 else text


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_documents_give_metadata_error_or_a_model(text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "METADATA.DIM"
        path.write_text(text)
        try:
            model = SpotModel.from_dimap(path)
        except MetadataError as exc:
            assert str(exc).startswith(str(path)), exc
            return
    cols, rows = model.size
    col, row, h = np.array([0.0, cols / 2]), np.array([0.0, rows / 2]), np.array([0.0, 100.0])
    col2, row2 = model.ground_to_image(*model.image_to_ground(col, row, h), h)
    assert np.isfinite(col2[1]), "a model that loads must at least locate its scene centre"
    ok = np.isfinite(col2)
    np.testing.assert_allclose(np.column_stack([col2, row2])[ok], np.column_stack([col, row])[ok], atol=1e-4)
