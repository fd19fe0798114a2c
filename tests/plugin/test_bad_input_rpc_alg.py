"""pushbroom:createblock on an image whose RPC has a pole inside its validity domain (issue 19): refused with
the engine's message naming the file and the place, in Processing and through qgis_process (before the fix
it was accepted and its footprint lay kilometres off)."""

import pytest
from qgis import processing

from tests.helpers.bad_inputs import processing_error
from tests.helpers.rpc_synthetic import raster_with_rpc

#: SAMP_DEN = 1 + 1.3 L: zero at L = -0.77, longitude 5.2 - 0.77 * 0.05 = 5.1615; the grid node of the other
#: sign nearest the centre is L = -0.8, longitude 5.16
POLED = {"SAMP_DEN_COEFF": [1.0, 1.3] + [0.0] * 18}


def test_createblock_refuses_an_rpc_with_a_pole(pushbroom_provider, tmp_path):
    good = raster_with_rpc(tmp_path / "good.tif")
    poled = raster_with_rpc(tmp_path / "poled.tif", **POLED)
    message = processing_error(
        "pushbroom:createblock", {"IMAGES": [str(good), str(poled)], "OUTPUT": str(tmp_path / "b.gpkg")}
    )
    # the file first, then the denominator and the image coordinate it belongs to
    assert f"{poled}: SAMP_DEN_COEFF, the denominator of the image column, changes sign" in message
    # the place: the centre, and the grid point nearest it beyond the pole at 5.1615 deg
    assert (
        "it is +1 at the centre (lon 5.200000, lat 44.100000, h 500 m) and -0.04 at lon 5.160000, lat "
        "44.100000, h 500 m, so the column has a pole in between"
    ) in message
    assert "export the RPC again" in message  # what to do
    assert not (tmp_path / "b.gpkg").exists()  # refused before the block was written
    result = processing.run("pushbroom:createblock", {"IMAGES": [str(good)], "OUTPUT": str(tmp_path / "b.gpkg")})
    assert result["OUTPUT"] == str(tmp_path / "b.gpkg")  # the same RPC without the pole is fine


@pytest.mark.slow
def test_qgis_process_refuses_an_rpc_with_a_pole(qgis_process, tmp_path):
    poled = raster_with_rpc(tmp_path / "poled.tif", **POLED)
    with pytest.raises(RuntimeError) as err:
        qgis_process("run", "pushbroom:createblock", "--", f"IMAGES={poled}", f"OUTPUT={tmp_path / 'b.gpkg'}")
    # what the user reads on the terminal: the file and the pole, no traceback
    assert f"{poled}: SAMP_DEN_COEFF, the denominator of the image column, changes sign" in str(err.value)
    assert "Traceback" not in str(err.value)  # the engine's message, not a crash
