"""Property test of importpoints' CSV parser (control_points.read_csv): every mutation of a valid point file
(lines dropped, doubled or cut, cells emptied or replaced by text, NaN, huge numbers or garbage, delimiters
changed, bytes that are not UTF-8) gives the engine's error naming the file, or valid observations; never
another exception."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.errors import PushbroomError

IMAGES = {"HRG": 1, "HRS1": 2}
VALID = (
    "id,role,lon,lat,h,sigma_e,HRG_col,HRG_row,HRS1_col,HRS1_row,HRS1_sigma\n"
    "P1,control,-84.20,36.60,300.5,2.0,100.5,200.25,50.0,60.0,0.3\n"
    "P2,check,-84.21,36.61,310.0,,110.0,210.0,,,\n"
    "P3,,-84.22,36.62,320.0,1.5,120.0,220.0,70.5,80.5,\n"
)
CELLS = st.sampled_from(
    [
        "",
        "nan",
        "inf",
        "-inf",
        "1e308",
        "-1e400",
        "abc",
        "0",
        "-0.0",
        "1,5",
        '"x"',
        "\x00",
        " 12 ",
        "control",
        "check",
        "tie",
        "P1",
        "é",
        "999999999999999999999",
    ]
)


@st.composite
def mutated(draw):
    lines = VALID.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["drop", "double", "cut", "cell", "delimiter", "swap"]))
        if action == "drop" and len(lines) > 1:
            lines.pop(k)
        elif action == "double":
            lines.insert(k, lines[k])
        elif action == "cut":
            lines[k] = lines[k][: draw(st.integers(0, max(len(lines[k]) - 1, 0)))]
        elif action == "cell":
            cells = lines[k].split(",")
            cells[draw(st.integers(0, len(cells) - 1))] = draw(CELLS)
            lines[k] = ",".join(cells)
        elif action == "delimiter":
            lines[k] = lines[k].replace(",", draw(st.sampled_from([";", "\t", " ", ",,"])))
        elif action == "swap" and len(lines) > 1:
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
    data = "\n".join(lines).encode("utf-8")
    if draw(st.booleans()):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(min_size=1, max_size=8)) + data[at:]
    return data


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=mutated(), crs=st.sampled_from([None, "EPSG:32616"]))
def test_mutated_point_files_give_observations_or_the_engines_error(tmp_path, data, crs):
    path = tmp_path / "points.csv"
    path.write_bytes(data)
    try:
        obs = cp.read_csv(path, IMAGES, cp.CsvOptions(crs=crs))
    except PushbroomError as exc:
        assert str(path) in str(exc) or "point" in str(exc)  # the message says which file or point
        return
    p, m = obs.points, obs.measurements
    # what comes back is usable: named, finite WGS 84 positions, positive sigmas, measurements of known images
    assert len(p) and all(name for name in p["name"])
    assert np.isfinite(p["lon"]).all() and np.isfinite(p["lat"]).all() and np.isfinite(p["h"]).all()
    assert (np.abs(p["lat"]) <= 90).all()
    assert all(math.isfinite(s) and s > 0 for key in ("sigma_e", "sigma_n", "sigma_h") for s in p[key])
    assert set(m["image_id"].tolist()) <= set(IMAGES.values())
    assert np.isfinite(m["col"]).all() and np.isfinite(m["row"]).all() and (m["sigma"] > 0).all()


@pytest.mark.parametrize("name", ["\x00", "P\x00", "P\t1"])
def test_a_point_id_with_a_control_character_is_an_error(tmp_path, name):
    """A NUL in an id was read as an empty name, or as another point's ("P\\x00" is "P" in numpy's text)."""
    path = tmp_path / "points.csv"
    path.write_text(VALID.replace("P1,", f"{name},"))
    with pytest.raises(PushbroomError, match=rf"{path} line 2: the point id must have 1 to 32 printable characters"):
        cp.read_csv(path, IMAGES)


def test_unicode_text_of_spreadsheets_is_read_like_utf8(tmp_path):
    """UTF-16 with or without a byte order mark, UTF-8 with one, UTF-32: what spreadsheets save as "Unicode
    text" (before: the "'utf-8' codec can't decode byte 0xff" text)."""
    (tmp_path / "utf8.csv").write_bytes(VALID.encode("utf-8"))
    expected = cp.read_csv(tmp_path / "utf8.csv", IMAGES)
    for encoding in ("utf-16", "utf-16-le", "utf-16-be", "utf-8-sig", "utf-32"):
        path = tmp_path / f"{encoding}.csv"
        path.write_bytes(VALID.replace("\n", "\r\n").encode(encoding))
        obs = cp.read_csv(path, IMAGES)
        assert list(obs.points["name"]) == list(expected.points["name"]) == ["P1", "P2", "P3"]
        assert np.array_equal(obs.points["h"], expected.points["h"])  # the same numbers, exactly
        assert np.array_equal(obs.measurements["col"], expected.measurements["col"])


def test_a_file_in_another_encoding_is_named_with_the_byte_and_line(tmp_path):
    path = tmp_path / "latin1.csv"
    path.write_bytes(VALID.replace("P2", "Pé").encode("latin-1"))
    at = VALID.index("P2") + 1  # the byte of é, on the third line
    with pytest.raises(
        PushbroomError,
        match=rf"the point file {path} is not UTF-8 text: byte {at} \(line 3, "
        r"b'\\xe9'\) is not valid there. Save it as UTF-8",
    ):
        cp.read_csv(path, IMAGES)
