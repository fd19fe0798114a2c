"""Bad RPC input raises MetadataError saying what is wrong and where; never a bare KeyError,
ValueError or IndexError. Mutated files (hypothesis) either load or raise MetadataError."""

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from pushbroom.algorithms import sensors
from pushbroom.algorithms.errors import MetadataError
from pushbroom.algorithms.sensors.rpc import RpcCoefficients, RpcModel
from pushbroom.algorithms.sensors.rpc_io import write_rpb, write_rpc_txt
from tests.helpers.rpc_synthetic import geom_text, synthetic_coefficients, synthetic_fields, write_raster


def _set(key, value):
    return lambda f: f.__setitem__(key, value)


def _set_coefficient(key, index, value):
    def change(f):
        f[key] = list(f[key])
        f[key][index] = value

    return change


BAD_FIELDS = [
    (lambda f: f.pop("LINE_OFF"), "missing LINE_OFF"),
    (lambda f: [f.pop(k) for k in ("SAMP_NUM_COEFF", "LAT_SCALE")], "missing LAT_SCALE, SAMP_NUM_COEFF"),
    (_set("SAMP_SCALE", "abc"), "SAMP_SCALE is not a number: 'abc'"),
    (_set("LAT_OFF", "nan"), r"LAT_OFF is not finite \(nan\)"),
    (_set("LONG_OFF", "-inf"), "LONG_OFF is not finite"),
    (_set("HEIGHT_SCALE", "0"), "HEIGHT_SCALE is 0: a scale is the positive half-range"),
    (_set("LINE_SCALE", ""), "LINE_SCALE is not a number"),
    (
        lambda f: f.__setitem__("LINE_NUM_COEFF", f["LINE_NUM_COEFF"][:19]),
        "LINE_NUM_COEFF has 19 values; RPC00B needs 20",
    ),
    (lambda f: f.__setitem__("SAMP_DEN_COEFF", " ".join(["1"] * 21)), "SAMP_DEN_COEFF has 21 values"),
    (_set_coefficient("SAMP_DEN_COEFF", 5, "NaN"), r"SAMP_DEN_COEFF\[6\] is not finite"),
    (_set_coefficient("LINE_NUM_COEFF", 19, "1.2.3"), r"LINE_NUM_COEFF\[20\] is not a number"),
    (_set_coefficient("LINE_DEN_COEFF", 0, 0.0), "LINE_DEN_COEFF vanishes at the normalisation centre"),
    # values that describe no image of a place on Earth (before: "singular Jacobian ... Is the point inside the
    # image" when the first image point was projected)
    (_set("LAT_SCALE", -0.099), "LAT_SCALE is -0.099: a scale is the positive half-range"),
    (
        _set("LAT_OFF", 120.0),
        r"LAT_OFF 120 \+- LAT_SCALE 0.099 is no latitude range \(-90 .. 90 degrees\) "
        r"\(LAT_OFF and LONG_OFF swapped\?\)",
    ),
    (_set("LONG_OFF", 400.0), r"LONG_OFF 400 is no longitude"),
    (
        _set("LINE_NUM_COEFF", [0.0] * 20),
        "LINE_NUM_COEFF is all zeros: every ground point would have the same image row",
    ),
    (
        _set("SAMP_NUM_COEFF", [0.0, 0.0204, -1.032] + [0.0] * 17),
        "the image column and row change along one ground direction only",
    ),
    # hypothesis's example (test_bad_input_rpc): a coefficient at the float range's end overflowed with a warning
    (_set_coefficient("SAMP_NUM_COEFF", 1, -1e308), "the image column is not a finite number at lon"),
]


@pytest.mark.parametrize("spoil, message", BAD_FIELDS)
def test_bad_fields_raise_metadata_error(spoil, message):
    fields = synthetic_fields()
    spoil(fields)
    with pytest.raises(MetadataError, match=message) as err:
        RpcCoefficients.from_fields(fields, "the-source.txt")
    assert str(err.value).startswith("the-source.txt: ") and "export the RPC again" in str(err.value)


def test_lat_off_and_long_off_swapped_are_named(tmp_path):
    """The synthetic RPC moved to longitude -84.2, latitude 36.6 (where its pixels are about square: the
    offsets of the 3 km simulated scene), then its offsets swapped in its _RPC.TXT: latitude -84.2, where a
    degree of longitude spans a tenth of the metres, so its pixels would be 8 times longer than wide."""
    fields = dict(synthetic_fields(), LONG_OFF=-84.2, LAT_OFF=36.6)
    write_rpc_txt(RpcModel(RpcCoefficients.from_fields(fields)), tmp_path / "moved_RPC.TXT")
    sensors.load(tmp_path / "moved_RPC.TXT")  # a valid RPC at its new place
    fields["LONG_OFF"], fields["LAT_OFF"] = fields["LAT_OFF"], fields["LONG_OFF"]
    path = tmp_path / "swapped_RPC.TXT"
    write_rpc_txt(RpcModel(RpcCoefficients.from_fields(fields)), path)
    with pytest.raises(
        MetadataError,
        match=re.escape(str(path)) + r": its pixels would cover .* m on the ground at "
        r"its centre, (\d+\.\d) times longer than wide: .*\(LAT_OFF and "
        r"LONG_OFF swapped",
    ) as err:
        sensors.load(path)
    # the pixel's elongation: cos(36.6 deg) / cos(84.2 deg) = 7.9 times the moved RPC's own (1.2 at most)
    assert 6.0 < float(re.search(r"(\d+\.\d) times", str(err.value)).group(1)) < 10.0


@pytest.fixture
def rpc_txt(tmp_path):
    path = tmp_path / "img_RPC.TXT"
    write_rpc_txt(RpcModel(synthetic_coefficients()), path)
    return path


def test_truncated_rpc_txt(rpc_txt):
    text = rpc_txt.read_text()
    rpc_txt.write_text(text[: len(text) // 2])
    with pytest.raises(MetadataError, match=re.escape(str(rpc_txt)) + r": missing [A-Z_]+_COEFF_\d+.*truncated"):
        sensors.load(rpc_txt)


def test_rpc_txt_missing_one_coefficient(rpc_txt):
    rpc_txt.write_text(re.sub(r"LINE_DEN_COEFF_7:.*\n", "", rpc_txt.read_text()))
    with pytest.raises(MetadataError, match="missing LINE_DEN_COEFF_7; a _RPC.TXT needs"):
        sensors.load(rpc_txt)


def test_rpc_txt_with_garbage_value(rpc_txt):
    rpc_txt.write_text(re.sub(r"HEIGHT_OFF: .*", "HEIGHT_OFF: twelve", rpc_txt.read_text()))
    with pytest.raises(MetadataError, match="HEIGHT_OFF is not a number: 'twelve'"):
        sensors.load(rpc_txt)


def test_truncated_rpb(tmp_path):
    path = tmp_path / "img.RPB"
    write_rpb(RpcModel(synthetic_coefficients()), path)
    path.write_text(path.read_text()[:1200])
    with pytest.raises(MetadataError, match="missing .*sampDenCoef.*not a complete RPC00B .RPB"):
        sensors.load(path)


def test_not_an_rpc_file_name(tmp_path):
    with pytest.raises(MetadataError, match="expected"):
        RpcModel.from_rpc_file(tmp_path / "notes.txt")


def test_missing_file():
    with pytest.raises(MetadataError, match="cannot read the RPC file"):
        RpcModel.from_rpc_file("/nonexistent/x_RPC.TXT")


def test_raster_without_rpc(tmp_path):
    raster = write_raster(tmp_path / "plain.tif")
    with pytest.raises(MetadataError, match="carries no RPC.*no .geom of the same name"):
        sensors.load(raster)


def test_file_that_is_not_a_raster(tmp_path):
    (tmp_path / "fake.tif").write_text("not a tiff")
    with pytest.raises(MetadataError, match="GDAL cannot open it as a raster"):
        sensors.load(tmp_path / "fake.tif")


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t.replace("polynomial_format:  B\n", ""), "polynomial_format is None, expected A or B"),
        (lambda t: t.replace("polynomial_format:  B", "polynomial_format:  C"), "polynomial_format is 'C'"),
        (lambda t: re.sub(r"samp_num_coeff_13:.*\n", "", t), "missing samp_num_coeff_13"),
        (lambda t: re.sub(r"number_lines:.*", "number_lines:  many", t), "number_samples / number_lines must both"),
        (lambda t: re.sub(r"number_samples:.*", "number_samples:  0", t), "image size .* is not positive"),
        (lambda t: re.sub(r"lat_scale:.*", "lat_scale:  0.0", t), "LAT_SCALE is 0: a scale is the positive"),
    ],
)
def test_bad_geom(tmp_path, edit, message):
    path = tmp_path / "bad.geom"
    path.write_text(edit(geom_text(synthetic_fields())))
    with pytest.raises(MetadataError, match=message):
        sensors.load(path)


def test_geom_beside_a_georeferenced_raster(tmp_path):
    (tmp_path / "ortho.geom").write_text(geom_text(synthetic_fields()))
    write_raster(tmp_path / "ortho.tif", geotransform=(600000.0, 0.5, 0, 4900000.0, 0, -0.5))
    with pytest.raises(MetadataError, match="is not a pixel offset into the sensor image"):
        sensors.load(tmp_path / "ortho.geom")


# -- mutation testing ---------------------------------------------------------------------------

NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
GARBAGE = st.sampled_from(
    [
        "",
        "nan",
        "NaN",
        "inf",
        "-inf",
        "0",
        "0.0",
        "abc",
        "1e999",
        "--1",
        "1,2",
        "(",
        ")",
        ";",
        ":",
        "  ",
        "\x00",
        "1 2 3",
        "\u00e9",
    ]
)


def mutate(data, text):
    """Up to 4 edits: delete a line, replace a number of a value by garbage, truncate the text."""
    for _ in range(data.draw(st.integers(1, 4))):
        lines = text.splitlines(keepends=True)
        if not lines:
            break
        op = data.draw(st.sampled_from(["delete", "replace", "replace", "replace", "truncate"]))
        i = data.draw(st.integers(0, len(lines) - 1))
        if op == "delete":
            del lines[i]
        elif op == "replace":
            separator = re.search("[:=]", lines[i])
            numbers = list(NUMBER.finditer(lines[i], separator.end() if separator else 0))
            if numbers:
                m = data.draw(st.sampled_from(numbers))
                lines[i] = lines[i][: m.start()] + data.draw(GARBAGE) + lines[i][m.end() :]
        else:
            cut = data.draw(st.integers(0, len(text)))
            lines = [text[:cut]]
        text = "".join(lines)
    return text


def load_or_metadata_error(name, text):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_text(text, encoding="utf-8")
        try:
            model = sensors.load(path)
        except MetadataError:
            return
        model.ground_to_image(np.array([5.28]), np.array([44.1]), np.array([1000.0]))


VALID = {"img_RPC.TXT": None, "img.RPB": None, "img.geom": None}


def valid_text(name):
    """The synthetic RPC as a valid file of the kind `name` names."""
    if VALID[name] is None:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / name
            if name.endswith(".geom"):
                path.write_text(geom_text(synthetic_fields()))
            else:
                (write_rpb if name.endswith(".RPB") else write_rpc_txt)(RpcModel(synthetic_coefficients()), path)
            VALID[name] = path.read_text()
    return VALID[name]


@pytest.mark.parametrize("name", sorted(VALID))
@settings(max_examples=50, deadline=None)
@given(data=st.data())
def test_mutated_rpc_files_load_or_raise_metadata_error(name, data):
    load_or_metadata_error(name, mutate(data, valid_text(name)))
