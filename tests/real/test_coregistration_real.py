"""Co-registration (quality.coregistration, Nuth and Kääb 2011) of the Ventoux pair's dense 2 m DSM to the SRTM
tile (EGM96 heights), issue 40: the shift found and dh before and after. The DSM covers 204 x 88 m, about three
cells of SRTM's 3" grid (78 m): its slope faces one way and its errors count once per SRTM cell, so the horizontal
shift is not shown, and the step must say so rather than return one. The vertical offset and the tilt are: the
DSM - SRTM comparison as it lies holds a west-east plane that makes most of its NMAD (docs/validation.md#dense-real),
and the tilt is that plane, so it takes dh's NMAD down to the plane-free figure. Bounds are today's."""

import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.quality.coregistration import CoregParams, ShiftNotShownError, coregister
from pushbroom.algorithms.quality.height_differences import Reference
from tests.helpers.real_dsm import VENTOUX_CELL, cut, refined_dense_points, srtm_comparison, stats_row


def test_ventoux_dense_dsm_coregistered_to_srtm(ventoux_pair, figures, tmp_path):
    models = [sensors.load(p) for p in ventoux_pair]
    points, _ = refined_dense_points(
        ventoux_pair, models, [p.stem for p in ventoux_pair], tmp_path / "dense", models[0].height_range
    )
    (tmp_path / "dsm").mkdir()
    srtm = str(ventoux_pair[0].with_name("N44E005.hgt"))
    dense = srtm_comparison(
        cut({1: models[0], 2: models[1]}, points.observations), srtm, (VENTOUX_CELL,), VENTOUX_CELL, tmp_path / "dsm"
    )
    dem, reference = str(tmp_path / "dsm" / f"dsm_{VENTOUX_CELL:g}m.tif"), Reference(srtm, "orthometric")
    try:  # no `pytest.raises(...) as`: its traceback would keep this frame, and GDAL's objects, past QGIS's exit
        coregister(dem, reference, CoregParams(tilt=True))
    except ShiftNotShownError as exc:
        refused = str(exc)
    else:
        pytest.fail("the Ventoux DSM's horizontal shift was found, not refused")
    assert "does not show the horizontal shift" in refused
    vertical = coregister(dem, reference, CoregParams(horizontal=False))
    tilt = coregister(dem, reference, CoregParams(horizontal=False, tilt=True))
    figures.report("Ventoux dense 2 m DSM against SRTM, shift and tilt", [refused])
    figures.table(
        "Ventoux dense 2 m DSM co-registered to SRTM, the vertical offset alone and with the tilt (m; tilt m/m)",
        [
            {
                "": label,
                "up": r.shift.up,
                "sigma up": r.sigma[2],
                "tilt east": r.shift.tilt_east,
                "tilt north": r.shift.tilt_north,
                "iterations": r.iterations,
            }
            for label, r in (("vertical", vertical), ("vertical and tilt", tilt))
        ],
    )
    figures.table(
        "Ventoux dense 2 m DSM - SRTM on the stable cells (m)",
        [
            stats_row("as it lies", vertical.before),
            stats_row("after the vertical offset", vertical.after),
            stats_row("after the vertical offset and the tilt", tilt.after),
            stats_row("all cells, without the least-squares plane", dense["detrended"]),
        ],
    )
    plane = dense["plane"][1]
    assert abs(tilt.shift.tilt_east + plane) < 0.2 * abs(plane)
    assert tilt.after.nmad < 0.5 * tilt.before.nmad and tilt.after.nmad < 1.1 * dense["detrended"].nmad
    assert abs(vertical.after.mean) < 0.05 and abs(tilt.after.mean) < 0.05  # least squares: the mean, not the median
