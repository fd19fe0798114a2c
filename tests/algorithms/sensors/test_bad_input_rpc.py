"""Bad RPC input (issue 19): an RPC whose denominator changes sign over its validity domain is refused
by every reader with the file and the place named, real and fitted RPCs pass; mutated _RPC.TXT, .RPB
and OSSIM .geom files (hypothesis) load as a usable model or raise the engine's own error."""

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from pushbroom.algorithms import sensors
from pushbroom.algorithms.errors import MetadataError, PushbroomError
from pushbroom.algorithms.sensors.base import SensorModel
from pushbroom.algorithms.sensors.rpc import RpcCoefficients, RpcModel, domain_grid, rpc_terms
from pushbroom.algorithms.sensors.rpc_io import write_rpb, write_rpc_txt
from tests.helpers.rpc_synthetic import geom_text, synthetic_coefficients, synthetic_fields, write_raster

#: the line denominator 1 + 1.5 P of a poled RPC vanishes at P = -2/3, inside the domain [-1, 1]
POLE_P = -2.0 / 3.0


def poled_fields():
    """The synthetic RPC with LINE_DEN_COEFF = 1 + 1.5 P: a pole of the row at a third of the way
    from the southern edge of the domain to its centre."""
    fields = synthetic_fields()
    fields["LINE_DEN_COEFF"] = [1.0, 0.0, 1.5] + [0.0] * 17
    return fields


def write_poled(kind, folder):
    """The poled RPC as a file of `kind` ('_RPC.TXT', '.RPB', '.geom', '.tif' with RPC tags)."""
    fields = poled_fields()
    if kind == ".tif":
        return write_raster(folder / "poled.tif", rpc=fields)
    if kind == ".geom":
        (folder / "poled.geom").write_text(geom_text(fields))
        return folder / "poled.geom"
    values = {k: " ".join(map(repr, np.atleast_1d(v).astype(float))) for k, v in fields.items()}
    path = folder / ("poled_RPC.TXT" if kind == "_RPC.TXT" else "poled.RPB")
    lines = [f"{k}: {v}" for k, v in values.items() if not k.endswith("COEFF")]
    if kind == "_RPC.TXT":
        lines += [
            f"{k}_{j}: {c}" for k, v in values.items() if k.endswith("COEFF") for j, c in enumerate(v.split(), start=1)
        ]
        path.write_text("\n".join(lines) + "\n")
    else:
        names = {
            "LINE_OFF": "lineOffset",
            "SAMP_OFF": "sampOffset",
            "LAT_OFF": "latOffset",
            "LONG_OFF": "longOffset",
            "HEIGHT_OFF": "heightOffset",
            "LINE_SCALE": "lineScale",
            "SAMP_SCALE": "sampScale",
            "LAT_SCALE": "latScale",
            "LONG_SCALE": "longScale",
            "HEIGHT_SCALE": "heightScale",
            "LINE_NUM_COEFF": "lineNumCoef",
            "LINE_DEN_COEFF": "lineDenCoef",
            "SAMP_NUM_COEFF": "sampNumCoef",
            "SAMP_DEN_COEFF": "sampDenCoef",
        }
        body = [
            f"\t{names[k]} = ({', '.join(v.split())});" if k.endswith("COEFF") else f"\t{names[k]} = {v};"
            for k, v in values.items()
        ]
        path.write_text("BEGIN_GROUP = IMAGE\n" + "\n".join(body) + "\nEND_GROUP = IMAGE\nEND;\n")
    return path


@pytest.mark.parametrize("kind", ["_RPC.TXT", ".RPB", ".geom", ".tif"])
def test_a_denominator_changing_sign_is_refused_by_every_reader(tmp_path, kind):
    path = write_poled(kind, tmp_path)
    with pytest.raises(MetadataError) as err:
        sensors.load(path)
    text = str(err.value)
    assert text.startswith(f"{path}: LINE_DEN_COEFF")  # the file and the culprit first
    assert "changes sign within the RPC's validity domain" in text and "pole" in text  # what is wrong
    lat = float(re.search(r"\+1 at the centre \(lon [\d.]+, lat ([\d.]+)", text).group(1))
    where = float(re.search(r"-[\d.e+-]+ at lon [\d.]+, lat ([\d.]+)", text).group(1))
    fields = synthetic_fields()
    # the place named lies south of the pole (P < -2/3), one grid step (0.1 P) from it at most
    assert fields["LAT_OFF"] + (POLE_P - 0.1) * fields["LAT_SCALE"] - 1e-6 <= where
    assert where < fields["LAT_OFF"] + POLE_P * fields["LAT_SCALE"] < lat  # the pole lies between the two


def test_a_denominator_reaching_zero_on_the_grid_is_refused():
    fields = synthetic_fields()
    fields["SAMP_DEN_COEFF"] = [1.0, 1.0] + [0.0] * 18  # 1 + L: zero on the domain's western edge
    with pytest.raises(
        MetadataError,
        match=r"SAMP_DEN_COEFF, the denominator of the image column, changes sign.*"
        r"\+0 at lon",
    ):
        RpcCoefficients.from_fields(fields, "edge_RPC.TXT")


def test_a_pole_just_outside_the_domain_is_accepted():
    fields = synthetic_fields()
    fields["LINE_DEN_COEFF"] = [1.0, 0.0, 0.99] + [0.0] * 17  # 1 + 0.99 P > 0 on [-1, 1]
    assert RpcCoefficients.from_fields(fields, "near_RPC.TXT").line_den[2] == 0.99  # read, not refused


def test_image_coordinates_that_overflow_are_refused():
    fields = synthetic_fields()
    fields["LINE_NUM_COEFF"] = list(fields["LINE_NUM_COEFF"])
    fields["LINE_NUM_COEFF"][11] = 1e308  # L^3: the row overflows away from the central meridian
    with pytest.raises(MetadataError, match="image row is not a finite number at lon"):
        RpcCoefficients.from_fields(fields, "huge_RPC.TXT")


def test_an_rpc_describing_no_image_is_refused():
    fields = synthetic_fields()
    fields["SAMP_OFF"] = -1e6  # the image would end 980 000 px left of its first column
    with pytest.raises(MetadataError, match="describe an image of -980000 x 42038 pixels"):
        RpcModel(RpcCoefficients.from_fields(fields, "neg_RPC.TXT"), source="neg_RPC.TXT")


def denominators_on_domain(model):
    t = rpc_terms(*domain_grid())
    return t @ model.coefficients.line_den, t @ model.coefficients.samp_den


def assert_near_one(model):
    for den in denominators_on_domain(model):
        assert 0.99 < den.min() and den.max() < 1.01  # Pleiades denominators stay within 1 % of 1


def test_real_triplet_rpcs_pass(triplet_image):
    assert_near_one(sensors.load(triplet_image))


def test_real_ventoux_rpcs_pass(ventoux_image):
    assert_near_one(sensors.load(ventoux_image))
    assert_near_one(sensors.load(ventoux_image.with_suffix(".geom")))


def test_a_fitted_rpc_keeps_its_denominators_sign_on_the_domain(tmp_path):
    from pushbroom.algorithms.sensors.rpc_fit import fit_rpc

    truth = RpcModel(synthetic_coefficients(), size=(2000, 2000))
    fitted, _ = fit_rpc(truth, truth.height_range, grid=(5, 5, 5))
    write_rpc_txt(fitted, tmp_path / "fitted_RPC.TXT")
    for den in denominators_on_domain(sensors.load(tmp_path / "fitted_RPC.TXT")):
        assert den.min() > 0  # den = 1 at the centre and positive throughout: no pole


# -- mutated RPC files ---------------------------------------------------------------------------

NUMBER = re.compile(rb"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
TEXT_VALUES = st.sampled_from(
    [
        b"",
        b"nan",
        b"NaN",
        b"inf",
        b"-inf",
        b"Infinity",
        b"1e999",
        b"-1e999",
        b"abc",
        b"--1",
        b"1,2",
        b"(",
        b")",
        b";",
        b":",
        b"=",
        b"\x00",
        b"1 2 3",
        b"0x10",
        b"1_000",
        "\u00e9".encode(),
    ]
)
FACTORS = st.sampled_from([0.0, -1.0, 1e-300, 1e300, 10.0, 0.1, 1.0 + 1e-9, 2.0, -1e308])


def change_number(data, line):
    """`line` with one number after its key replaced: scaled, negated, zeroed, or by a text value."""
    separator = re.search(rb"[:=]", line)
    numbers = list(NUMBER.finditer(line, separator.end() if separator else 0))
    if not numbers:
        return line
    m = data.draw(st.sampled_from(numbers))
    if data.draw(st.booleans()):
        value = repr(float(m.group()) * data.draw(FACTORS)).encode()
    else:
        value = data.draw(TEXT_VALUES)
    return line[: m.start()] + value + line[m.end() :]


def mutate(data, text):
    """Up to 5 edits of a file's bytes: delete, duplicate or move a line, change a number, insert garbage
    bytes, truncate; or the empty file."""
    if data.draw(st.integers(0, 20)) == 0:
        return b""
    for _ in range(data.draw(st.integers(1, 5))):
        lines = text.splitlines(keepends=True)
        if not lines:
            break
        op = data.draw(st.sampled_from(["delete", "duplicate", "move", "number", "number", "garbage", "truncate"]))
        i = data.draw(st.integers(0, len(lines) - 1))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(data.draw(st.integers(0, len(lines))), lines[i])
        elif op == "move":
            lines.insert(data.draw(st.integers(0, len(lines) - 1)), lines.pop(i))
        elif op == "number":
            lines[i] = change_number(data, lines[i])
        elif op == "garbage":
            at = data.draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:at] + data.draw(st.binary(min_size=1, max_size=8)) + lines[i][at:]
        else:
            lines = [text[: data.draw(st.integers(0, len(text)))]]
        text = b"".join(lines)
    return text


def valid_files():
    """{file name: bytes} of the synthetic RPC as a valid _RPC.TXT, .RPB and .geom."""
    model = RpcModel(synthetic_coefficients())
    with tempfile.TemporaryDirectory() as folder:
        write_rpc_txt(model, Path(folder) / "img_RPC.TXT")
        write_rpb(model, Path(folder) / "img.RPB")
        (Path(folder) / "img.geom").write_text(geom_text(synthetic_fields()))
        return {p.name: p.read_bytes() for p in Path(folder).iterdir()}


VALID = valid_files()


def assert_usable(model):
    """A model the engine can work with: a positive size and finite image positions of ground points
    over its validity domain."""
    assert isinstance(model, SensorModel) and min(model.size) >= 1  # an image of at least one pixel
    c = model.coefficients
    x, y, z = (v[::97] for v in domain_grid())
    col, row = model.ground_to_image(
        c.long_off + x * c.long_scale, c.lat_off + y * c.lat_scale, c.height_off + z * c.height_scale
    )
    assert np.isfinite(col).all() and np.isfinite(row).all()  # no pole or overflow over the domain


@pytest.mark.parametrize("name", sorted(VALID))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_mutated_rpc_files_give_a_usable_model_or_the_engines_error(name, data):
    text = mutate(data, VALID[name])
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / name
        path.write_bytes(text)
        try:
            model = sensors.load(path)
        except PushbroomError as exc:
            assert str(exc).startswith(str(path))  # the message names the file
            return
        assert_usable(model)
