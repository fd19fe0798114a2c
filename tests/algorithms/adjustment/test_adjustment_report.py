"""The bundle adjustment's outputs on a small simulated SPOT 5 triplet with injected look-angle
errors and measurement blunders: residual vectors of control/check points (against the
Adjustment's numbers, a numpy forward-intersection reference and OSR), tie point heights against
the true DSM/DTM (against a plain numpy bilinear interpolation; EGM96 references), and the report's
Kornus et al. 2006, Table 3/4 rows."""

import csv

import numpy as np
import pytest

from pushbroom.algorithms.adjustment import report
from pushbroom.algorithms.adjustment.bundle import AdjustmentSettings, adjust, check_points
from pushbroom.algorithms.adjustment.observations import MEAS_DTYPE, POINT_DTYPE, Observations
from pushbroom.algorithms.adjustment.residual_vectors import intersection_residuals, residual_vectors
from pushbroom.algorithms.adjustment.tie_heights import tie_height_differences
from pushbroom.algorithms.crs import egm96_undulation
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.geodesy import metres_per_degree, utm_epsg
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.stats import statistics_table
from tests.helpers.adjustment_scene import IDS, LABELS, NAMES, point_observations, scene_models
from tests.helpers.figures import section_rows
from tests.helpers.osr_oracle import utm
from tests.helpers.raster_oracle import bilinear

N_CONTROL = 14
SIGMA_PX = 0.3


def dsm_tie_points(scene, n, seed):
    """n tie points on the true DSM seen in the three images (truth models, SIGMA_PX noise)."""
    rng = np.random.default_rng(seed)
    truth = scene_models(scene, NAMES, truth=True)
    cols, rows = truth[1].size
    lon, lat, h = truth[1].image_to_dem(
        rng.uniform(30, cols - 30, n), rng.uniform(30, rows - 30, n), read_dem(scene["dsm"])
    )
    meas = []
    for i, model in truth.items():
        c, r = model.ground_to_image(lon, lat, h)
        meas += [(k, i, c[k] + rng.normal(0, SIGMA_PX), r[k] + rng.normal(0, SIGMA_PX), SIGMA_PX) for k in range(n)]
    points = np.zeros(n, POINT_DTYPE)
    points["name"], points["role"] = [f"T{k}" for k in range(n)], "tie"
    for key in ("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h"):
        points[key] = np.nan
    return Observations(points, np.array(meas, MEAS_DTYPE))


@pytest.fixture(scope="module")
def adjusted(simulated):
    """Supplied = truth + 20 urad look-angle offsets; 3 blunders among the point measurements;
    14 control points, the rest check; 300 tie points on the DSM; blunders removed by snooping."""
    scene = simulated(SceneConfig.small(points=30, error_scale=0.0, blunders=3))
    models = scene_models(scene, NAMES)
    for i, model in models.items():
        model.orientation.corrections.look[:, 0] = (2e-5, -2e-5 if i % 2 else 2e-5)
    obs = point_observations(scene["points"], IDS, N_CONTROL, sigma_px=SIGMA_PX).concatenate(
        dsm_tie_points(scene, 300, 3)
    )
    result = adjust(
        models, obs, ["look:0"], names=LABELS, height=300.0, settings=AdjustmentSettings(remove_blunders=True)
    )
    check = check_points(result, obs, height=300.0)
    rows = list(csv.DictReader(open(scene["points"])))
    blunders = {r["id"] for r in rows if any(r[f"{n}_blunder"] == "1" for n in NAMES)}
    return scene, obs, result, check, blunders


def test_control_vectors_carry_the_adjustments_numbers(adjusted, figures):
    _, obs, result, check, blunders = adjusted
    vectors, crs = residual_vectors(result, check, obs, scale=50.0)
    pts, meas = result.observations.points, result.observations.measurements
    control = np.flatnonzero(pts["role"] == "control")
    ctrl = vectors[vectors["role"] == "control"]
    assert list(ctrl["name"]) == list(pts["name"][control])
    np.testing.assert_array_equal(
        np.column_stack([ctrl["dE"], ctrl["dN"], ctrl["dH"]]), result.ground_residuals[control]
    )
    np.testing.assert_array_equal(
        np.column_stack([ctrl["sigma_e"], ctrl["sigma_n"], ctrl["sigma_h"]]), result.point_sigmas[control]
    )
    for row, p in zip(ctrl, control):
        mine = meas["point"] == p
        assert row["rms_px"] == pytest.approx(np.sqrt(np.mean(result.residuals[mine] ** 2)), rel=1e-12)
        assert row["max_w"] == pytest.approx(np.max(np.abs(result.normalised[mine])), rel=1e-12)
        assert row["flagged"] == (row["max_w"] > 3.29)
    removed = {name for name, _, _ in result.removed}
    figures.report("removed by data snooping", result.removed)
    figures.report("blunders in", sorted(blunders))
    assert removed == blunders & set(pts["name"][control])
    assert not ctrl["flagged"].any()
    assert crs == f"EPSG:{utm_epsg(float(np.mean(pts['lon'][control])), float(np.mean(pts['lat'][control])))}"


def test_check_vectors_hold_their_intersection_residuals(adjusted, figures):
    """Check points: dE, dN, dH and sigmas of check_points; image residuals and redundancy numbers
    against a dense numpy intersection with finite-difference partials; the blundered check point
    (and only it) flagged."""
    _, obs, result, check, blunders = adjusted
    vectors, _ = residual_vectors(result, check, obs)
    chk = vectors[vectors["role"] == "check"]
    assert list(chk["name"]) == list(check["names"])
    np.testing.assert_array_equal(
        np.column_stack([chk["dE"], chk["dN"], chk["dH"]]), np.column_stack([check["dE"], check["dN"], check["dH"]])
    )
    np.testing.assert_array_equal(np.column_stack([chk["sigma_e"], chk["sigma_n"], chk["sigma_h"]]), check["sigma"])
    models = result.parameters.models
    for row in chk:
        k = np.flatnonzero(obs.points["name"] == row["name"])[0]
        p = obs.points[k]
        m = obs.measurements[obs.measurements["point"] == k]
        e_deg, n_deg = metres_per_degree(p["lat"], p["h"])
        ground = np.array([p["lon"] + row["dE"] / e_deg, p["lat"] + row["dN"] / n_deg, p["h"] + row["dH"]])

        def project(g):
            return np.array([models[int(i)].ground_to_image(*g) for i in m["image_id"]], float).ravel()

        steps = np.array([1.0 / e_deg, 1.0 / n_deg, 1.0])
        a = np.column_stack(
            [
                (project(ground + s * np.eye(3)[j]) - project(ground - s * np.eye(3)[j])) / 2.0
                for j, s in enumerate(steps)
            ]
        )  # px per m E, N, U
        v = project(ground) - np.column_stack([m["col"], m["row"]]).ravel()
        sigma = np.repeat(m["sigma"], 2)
        r = 1.0 - np.diag(a @ np.linalg.inv(a.T @ (a / sigma[:, None] ** 2)) @ a.T) / sigma**2
        mine = m.copy()
        mine["point"] = 0
        got_v, got_r = intersection_residuals(models, ground[:1], ground[1:2], ground[2:], mine)
        np.testing.assert_allclose(got_v, v.reshape(-1, 2), atol=1e-6)
        np.testing.assert_allclose(got_r, r.reshape(-1, 2), atol=1e-5)
        assert got_r.sum() == pytest.approx(2 * len(m) - 3)
        assert row["rms_px"] == pytest.approx(np.sqrt(np.mean(v**2)), abs=1e-6)
        assert row["max_w"] == pytest.approx(np.max(np.abs(v / (sigma * np.sqrt(r)))), rel=1e-4)
    figures.table("check points", [{"name": r["name"], "max |w|": r["max_w"]} for r in chk])
    assert set(chk["name"][chk["flagged"]]) == blunders & set(chk["name"])


def test_vector_geometry_against_osr(adjusted, figures):
    """Start: the reference position in UTM; end: start + scale x (dE, dN) along the UTM images of
    true east and north at the point (OSR, point by point)."""
    _, obs, result, check, _ = adjusted
    scale = 100.0
    vectors, crs = residual_vectors(result, check, obs, scale=scale, crs="EPSG:32617")
    assert crs == "EPSG:32617"  # a neighbouring zone: large meridian convergence
    ref = obs.points[[np.flatnonzero(obs.points["name"] == n)[0] for n in vectors["name"]]]
    x0, y0 = utm(ref["lon"], ref["lat"], 32617)
    np.testing.assert_allclose(vectors["x0"], x0, atol=1e-3)
    np.testing.assert_allclose(vectors["y0"], y0, atol=1e-3)
    e_deg, n_deg = metres_per_degree(ref["lat"], ref["h"])
    east = np.subtract(utm(ref["lon"] + 1.0 / e_deg, ref["lat"], 32617), (x0, y0))
    north = np.subtract(utm(ref["lon"], ref["lat"] + 1.0 / n_deg, 32617), (x0, y0))
    expected = np.array([x0, y0]) + scale * (vectors["dE"] * east + vectors["dN"] * north)
    length = scale * np.hypot(vectors["dE"], vectors["dN"])
    assert np.all(np.hypot(vectors["x1"] - expected[0], vectors["y1"] - expected[1]) < 1e-3 * length + 0.01)
    convergence = np.degrees(np.arctan2(north[0], north[1]))
    figures.report("meridian convergence in EPSG:32617", [convergence.min(), convergence.max()], "deg")
    assert np.all(np.abs(convergence) > 1.0)


def test_tie_heights_against_numpy_and_the_true_surface(adjusted, figures):
    """dh = adjusted - reference; on the DSM (where the tie points lie) as large as the adjusted
    points' height sigmas say, on the DTM larger and positive (trees and buildings, Kornus et al. 2006, section
    3.4.3.1)."""
    scene, _, result, _, _ = adjusted
    tie = result.observations.points["role"] == "tie"
    tables = {}
    for key in ("dsm", "dtm"):
        got = tie_height_differences(result, read_dem(scene[key]))
        assert got.outside == 0 and list(got.names) == list(result.observations.points["name"][tie])
        expected = result.h[tie] - bilinear(scene[key], result.lon[tie], result.lat[tie])
        np.testing.assert_allclose(got.dh, expected, atol=1e-6)
        tables[key] = statistics_table({"dh": got.dh})["dh"]
        figures.table(
            f"tie heights - {key} (m)", [{"n": tables[key][0], "mean": tables[key][2], "RMS": tables[key][4]}]
        )
    theoretical = np.sqrt(np.mean(result.point_sigmas[tie, 2] ** 2))
    figures.report("RMS of the adjusted tie points' sigma H", theoretical, "m")
    assert abs(tables["dsm"][2]) < 0.5 * theoretical and 0.7 < tables["dsm"][4] / theoretical < 1.4
    assert tables["dtm"][2] > tables["dsm"][2] + 1.0


def test_tie_heights_with_an_egm96_reference(adjusted):
    """An EGM96 (orthometric) copy of the DSM gives the ellipsoidal comparison back; a DEM covering
    half the block counts the other tie points as outside."""
    scene, _, result, _, _ = adjusted
    dsm = read_dem(scene["dsm"])
    lon0, dlon, _, lat0, _, dlat = dsm.geotransform
    rows, cols = dsm.shape
    lon, lat = np.meshgrid(lon0 + dlon * (np.arange(cols) + 0.5), lat0 + dlat * (np.arange(rows) + 0.5))
    undulation = egm96_undulation(lon, lat)
    assert np.all(np.abs(undulation) > 10.0)
    geoid = Dem(dsm.heights - undulation, dsm.geotransform)
    ellipsoidal = tie_height_differences(result, dsm)
    orthometric = tie_height_differences(result, geoid, "orthometric")
    np.testing.assert_allclose(orthometric.dh, ellipsoidal.dh, atol=0.01)
    unconverted = tie_height_differences(result, geoid)
    assert np.mean(unconverted.dh - ellipsoidal.dh) == pytest.approx(np.mean(undulation), abs=0.5)
    half = Dem(dsm.heights[: rows // 2], dsm.geotransform)
    part = tie_height_differences(result, half)
    assert 0 < part.outside < len(ellipsoidal.dh) and len(part.dh) + part.outside == len(ellipsoidal.dh)
    with pytest.raises(InputError, match="reference heights"):
        tie_height_differences(result, dsm, "geoid")


def test_report_tables(adjusted, tmp_path, figures):
    """Kornus et al. 2006, Tables 3 and 4 rows equal numpy statistics; the HTML page holds them as tables."""
    scene, obs, result, check, _ = adjusted
    table = statistics_table({k: check[k] for k in ("dE", "dN", "dH")})
    tie = tie_height_differences(result, read_dem(scene["dtm"]))
    vectors, _ = residual_vectors(result, check, obs)
    parts = report.sections(result, check, table, heights=(tie, "dtm.tif"), vectors=vectors)
    text = report.render_text(parts)
    for part in parts:
        figures.table(part.title, section_rows(part))
    dh = tie.dh
    want = [str(dh.size)] + [
        f"{v:.3f}" for v in (dh.min(), dh.mean(), dh.max(), np.sqrt(np.mean(dh**2)), np.std(dh, ddof=1))
    ]
    assert [line.split()[1:] for line in text.splitlines() if line.split()[:1] == ["dh"]] == [want]
    de = check["dE"]
    assert [line.split()[1:7] for line in text.splitlines() if line.split()[:1] == ["dE"]] == [
        [str(de.size)]
        + [f"{v:.3f}" for v in (de.min(), de.mean(), de.max(), np.sqrt(np.mean(de**2)), np.std(de, ddof=1))]
    ]
    assert text == report.text_report(result, check, table, heights=(tie, "dtm.tif"), vectors=vectors)
    page = open(report.write_html(tmp_path / "r.html", "Bundle adjustment", parts=parts)).read()
    assert page.count("<table>") == 5 and "Kornus et al. 2006, Table 4" in page
    assert "<td>dh</td>" + "".join(f"<td>{c}</td>" for c in want) in page
    for name in vectors["name"]:
        assert f"<td>{name}</td>" in page
