"""pushbroom:bundleadjust on a small simulated SPOT 5 triplet with injected look-angle errors:
the adjusted models land in the block and reproduce the true image positions of check points; the
residual-vector layer of control/check points (against the simulator's points and OSR) with its
style; the tie point heights against the true DTM (Kornus et al. 2006, Table 4) against a forward intersection with
the adjusted models and a numpy interpolation, for an ellipsoidal and an EGM96 reference."""

import csv
import re
import shutil

import numpy as np
import pytest
from qgis import processing
from qgis.core import (
    QgsCategorizedSymbolRenderer,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingOutputLayerDefinition,
    QgsProject,
    QgsVectorLayer,
    QgsWkbTypes,
)

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.control_points import import_csv
from pushbroom.algorithms.adjustment.observations import Observations
from pushbroom.algorithms.adjustment.residual_vectors import ATTRIBUTES
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.crs import egm96_undulation
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from tests.helpers.osr_oracle import utm
from tests.helpers.raster_oracle import bilinear

N_CONTROL = 19
N_TIE = 200


@pytest.fixture(scope="module")
def scene(simulated):
    return simulated(SceneConfig.small(points=30, error_scale=0.0))


def make_block(paths, path):
    """A block of the scene's triplet with 20 urad look-angle errors and the simulator's points
    (the first N_CONTROL control, the rest check); {name: image id}."""
    images = Block.open_images([paths["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    Block.create(path, images, height=300.0)
    ids = {r["name"]: r["id"] for r in Block(path).images()}
    models = {i: Block(path).model(i) for i in ids.values()}
    for i, model in models.items():  # inject 20 urad look-angle errors
        model.orientation.corrections.look[:, 0] = (2e-5, -2e-5 if i % 2 else 2e-5)
    Block(path).save_models(models, supplied=True)  # the supplied orientation, with its errors
    check = [r["id"] for r in csv.DictReader(open(paths["points"]))][N_CONTROL:]
    import_csv(Block(path), paths["points"], suffix="_meas", check_ids=check)
    return ids


def truth_rms(path, paths, ids):
    """{image name: RMS distance (px)} between where the block's models and the truth put the
    simulator's points."""
    rows = list(csv.DictReader(open(paths["points"])))
    ground = [np.array([float(r[k]) for r in rows]) for k in ("lon", "lat", "h")]
    out = {}
    for name, i in ids.items():
        col, row = Block(path).model(i).ground_to_image(*ground)
        true = np.array([[float(r[f"{name}_col"]), float(r[f"{name}_row"])] for r in rows])
        out[name] = float(np.sqrt(np.mean((col - true[:, 0]) ** 2 + (row - true[:, 1]) ** 2)))
    return out


@pytest.fixture(scope="module")
def adjusted_block(scene, tmp_path_factory):
    path = tmp_path_factory.mktemp("bundle") / "b.gpkg"
    return str(path), scene, make_block(scene, path)


def make_tie_block(scene, path):
    """make_block with N_TIE tie points on the true DSM (truth models, 0.2 px noise): (ids, observations)."""
    ids = make_block(scene, path)
    rng = np.random.default_rng(5)
    truth = {i: sensors.load(scene["truth_metadata"][n]) for n, i in ids.items()}
    cols, rows = truth[ids["HRG"]].size
    lon, lat, h = truth[ids["HRG"]].image_to_dem(
        rng.uniform(30, cols - 30, N_TIE), rng.uniform(30, rows - 30, N_TIE), read_dem(scene["dsm"])
    )
    pts = np.zeros(N_TIE, POINT_DTYPE)
    pts["id"], pts["group"] = np.arange(N_TIE), 3
    obs = np.zeros(3 * N_TIE, OBS_DTYPE)
    obs["point_id"] = np.repeat(np.arange(N_TIE), 3)
    for k, i in enumerate(truth):
        obs["image_id"][k::3] = i
        c, r = truth[i].ground_to_image(lon, lat, h)
        obs["col"][k::3], obs["row"][k::3] = c + rng.normal(0, 0.2, N_TIE), r + rng.normal(0, 0.2, N_TIE)
    Block(path).store_points(MultiPoints(pts, obs), "tie_points")
    return ids, obs


@pytest.fixture(scope="module")
def tie_block(scene, tmp_path_factory):
    path = tmp_path_factory.mktemp("bundle_tie") / "t.gpkg"
    return (str(path), scene, *make_tie_block(scene, path))


def test_adjusts_and_stores_models(pushbroom_provider, adjusted_block, tmp_path):
    path, paths, ids = adjusted_block
    result = processing.run(
        "pushbroom:bundleadjust",
        {
            "BLOCK": path,
            "FREE": "look:0",
            "USE_TIE_POINTS": False,
            "CONTROL_SERIES": "4,8,19",
            "REPORT": str(tmp_path / "r.html"),
        },
    )
    assert 0.3 < result["SIGMA0"] < 3.0
    text = open(result["REPORT"]).read()
    assert "HRS2 psi_y_0" in text and "<td>dH</td>" in text and "Kornus et al. 2006, Table 4" not in text
    series = re.findall(r"<tr><td>(\d+)</td><td>(\d+)</td><td>([\d.]+)</td><td>([\d.]+)</td><td>([\d.]+)</td>", text)
    assert [int(r[0]) for r in series] == [4, 8, 19] and len({r[1] for r in series}) == 1  # same check points
    assert float(series[0][4]) < 3.0 * float(series[-1][4])
    for i in ids.values():
        assert Block(path).model(i).orientation.corrections.look[0, 0] == pytest.approx(0.0, abs=3e-6)
    assert max(truth_rms(path, paths, ids).values()) < 0.3


def test_residual_vector_layer(pushbroom_provider, adjusted_block, tmp_path, log):
    """One line per control/check point from its reference position (UTM, OSR) to reference +
    scale x (dE, dN); the attributes match the logged table and the points' precision; the
    layer is loaded on completion with the arrow style."""
    path, paths, _ = adjusted_block
    rows = {r["id"]: r for r in csv.DictReader(open(paths["points"]))}
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    out = str(tmp_path / "residuals.gpkg")
    result = processing.run(
        "pushbroom:bundleadjust",
        {
            "BLOCK": path,
            "FREE": "look:0",
            "USE_TIE_POINTS": False,
            "VECTOR_SCALE": 250.0,
            "RESIDUALS": QgsProcessingOutputLayerDefinition(out, QgsProject.instance()),
        },
        context=context,
        feedback=log,
    )
    layer = QgsVectorLayer(result["RESIDUALS"], "residuals", "ogr")
    epsg = int(Block(path).info()["default_crs"].split(":")[1])
    assert layer.isValid() and layer.crs().authid() == f"EPSG:{epsg}"
    assert QgsWkbTypes.flatType(layer.wkbType()) == QgsWkbTypes.LineString
    assert [f.name() for f in layer.fields() if f.name() != "fid"] == list(ATTRIBUTES) + ["scale"]
    features = list(layer.getFeatures())
    roles = [f["role"] for f in features]
    assert roles.count("control") == N_CONTROL and roles.count("check") == len(rows) - N_CONTROL
    logged = "\n".join(log.messages)
    for f in features:
        r = rows[f["name"]]
        line = f.geometry().asPolyline()
        x0, y0 = utm([float(r["lon"])], [float(r["lat"])], epsg)
        assert line[0].x() == pytest.approx(x0[0], abs=1e-3) and line[0].y() == pytest.approx(y0[0], abs=1e-3)
        length = np.hypot(line[1].x() - line[0].x(), line[1].y() - line[0].y())
        assert length == pytest.approx(250.0 * np.hypot(f["dE"], f["dN"]), rel=2e-3, abs=0.01)
        assert f["scale"] == 250.0 and f["flagged"] == (f["max_w"] > 3.29)
        assert 0.0 < f["rms_px"] < 1.0
        sigma = np.array([f["sigma_e"], f["sigma_n"], f["sigma_h"]])
        assert np.all(np.abs([f["dE"], f["dN"], f["dH"]]) < 4.0 * sigma), (f["name"], f["dE"], f["dN"], f["dH"], sigma)
        assert re.search(rf"{f['name']}\s+{f['role']}\s+{f['dE']:.3f}\s+{f['dN']:.3f}\s+{f['dH']:.3f}", logged)
    details = context.layerToLoadOnCompletionDetails(result["RESIDUALS"])
    details.postProcessor().postProcessLayer(layer, context, log)
    renderer = layer.renderer()
    assert isinstance(renderer, QgsCategorizedSymbolRenderer)
    assert {c.value() for c in renderer.categories()} == {"control", "check", "control flagged", "check flagged"}


def _table_row(page, label):
    cells = re.search(rf"<tr><td>{label}</td>((?:<td>[^<]*</td>)+)</tr>", page).group(1)
    return [float(c) for c in re.findall(r"<td>([^<]*)</td>", cells)]


def test_tie_heights_against_the_reference_dtm(pushbroom_provider, tie_block, tmp_path, figures):
    """Kornus et al. 2006, Table 4: the adjusted tie points are the forward intersections with the adjusted models;
    their heights minus the DTM interpolated in numpy give the table's n, min, mean, max, RMS and
    sigma. The DTM read as EGM96 heights shifts every dh by minus the geoid undulation."""
    path, paths, ids, obs = tie_block
    tables = {}
    for key, datum in (("ellipsoidal", 0), ("egm96", 1)):
        report = tmp_path / f"{key}.html"
        processing.run(
            "pushbroom:bundleadjust",
            {
                "BLOCK": path,
                "FREE": "look:0",
                "USE_TIE_POINTS": True,
                "REFERENCE_DEM": paths["dtm"],
                "REFERENCE_HEIGHTS": datum,
                "REPORT": str(report),
            },
        )
        page = report.read_text()
        assert "Kornus et al. 2006, Table 4" in page
        tables[key] = _table_row(page, "dh")
    models = {i: Block(path).model(i) for i in ids.values()}
    cut = intersect(models, Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"], 0.5), h0=300.0)
    assert cut.ok.all()
    dh = cut.h - bilinear(paths["dtm"], cut.lon, cut.lat)
    want = [dh.size, dh.min(), dh.mean(), dh.max(), np.sqrt(np.mean(dh**2)), np.std(dh, ddof=1)]
    figures.table("tie heights - DTM (m)", [dict(zip(("n", "min", "mean", "max", "RMS", "sigma"), want))])
    np.testing.assert_allclose(tables["ellipsoidal"], want, atol=2e-3)
    undulation = egm96_undulation(cut.lon, cut.lat)
    assert tables["egm96"][2] == pytest.approx(np.mean(dh - undulation), abs=2e-3)
    assert tables["egm96"][2] - tables["ellipsoidal"][2] > 25.0  # N is about -31 m here


def test_clear_errors(pushbroom_provider, adjusted_block):
    path = adjusted_block[0]
    with pytest.raises(QgsProcessingException, match="no orientation parameter matches"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "psi_q_0", "USE_TIE_POINTS": False})
    with pytest.raises(QgsProcessingException, match="tie points"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "look:0", "USE_TIE_POINTS": True})


def test_an_unconverged_adjustment_fails_and_stores_nothing(pushbroom_provider, adjusted_block, tmp_path):
    """MAX_ITERATIONS 1 from the injected 20 urad: one QgsProcessingException saying so, the block's models
    as they were, and the report written with the alert first."""
    path = adjusted_block[0]
    before = Block(path).generations()
    report = tmp_path / "r.html"
    with pytest.raises(QgsProcessingException, match=r"did not converge in 1 iteration.*nothing was stored"):
        processing.run(
            "pushbroom:bundleadjust",
            {"BLOCK": path, "FREE": "look:0", "USE_TIE_POINTS": False, "MAX_ITERATIONS": 1, "REPORT": str(report)},
        )
    assert Block(path).generations() == before
    assert report.read_text().index("class='alert'") < report.read_text().index("<h2>Adjustment</h2>")


def test_automatic_selection_and_variance_components(pushbroom_provider, scene, tmp_path, log):
    """FREE = auto (the default): the injected look-angle constants are chosen and the adjusted models
    put the simulator's points where the truth does; the selection's steps and the variance components
    are in the log and the report; the tie points' sigma comes out near their simulated 0.2 px
    instead of the a priori 0.5 px."""
    path, paths = str(tmp_path / "auto.gpkg"), scene
    ids, _ = make_tie_block(paths, path)
    result = processing.run(
        "pushbroom:bundleadjust", {"BLOCK": path, "REPORT": str(tmp_path / "auto.html")}, feedback=log
    )
    text = open(result["REPORT"]).read()
    assert "Parameter selection (Kornus et al. 2006, section 3.4.3)" in text and "Variance components" in text
    assert any(m.startswith("step 1: fixed") for m in log.messages)
    assert 0.8 < result["SIGMA0"] < 1.2
    tie_sigma = re.search(r"<td>tie image</td><td>\d+</td><td>[\d.]+</td><td>[\d.]+</td><td>([\d.]+)</td>", text)
    assert tie_sigma and 0.15 < float(tie_sigma.group(1)) < 0.25
    selected = re.findall(
        r"^selected \d+ free coefficient\(s\) in \d+ adjustments: (.*)$", "\n".join(log.messages), re.MULTILINE
    )
    chosen = set(selected[-1].split(", "))
    assert {f"{n} {k}_0" for n in ids for k in ("psi_x", "psi_y")} <= chosen
    assert max(truth_rms(path, paths, ids).values()) < 0.3
    # adjusting the adjusted block again starts from the supplied orientation: the same selection in as many
    # adjustments, the same models (a restart from the adjusted models fixed every coefficient one by one)
    first = [Block(path).model(i).orientation.corrections.look.copy() for i in ids.values()]
    again, progress = type(log)(), []
    again.progressChanged.connect(progress.append)
    processing.run("pushbroom:bundleadjust", {"BLOCK": path}, feedback=again)
    assert [m for m in again.messages if m.startswith("selected ")] == [
        m for m in log.messages if m.startswith("selected ")
    ]
    for i, look in zip(ids.values(), first):
        np.testing.assert_allclose(Block(path).model(i).orientation.corrections.look, look, rtol=0, atol=1e-12)
    # progress moves with every adjustment of the selection: no stretch of adjustments without a report
    count = int(
        re.search(r"in (\d+) adjustments", next(m for m in again.messages if m.startswith("selected "))).group(1)
    )
    assert len(set(progress)) >= count // 2 and progress == sorted(progress)


def test_lagrange_model(pushbroom_provider, adjusted_block, tmp_path, log):
    """MODEL = Lagrange: the attitude at 2 orientation images free (on this 3 km block the offsets
    would be a named defect with the roll: 600 lines between the orientation images) puts the
    simulator's points where the truth does."""
    source, paths, ids = adjusted_block
    path = str(tmp_path / "lagrange.gpkg")
    shutil.copy(source, path)
    result = processing.run(
        "pushbroom:bundleadjust",
        {
            "BLOCK": path,
            "MODEL": 1,
            "ORIENTATION_IMAGES": 2,
            "FREE": "lagrange:attitude",
            "USE_TIE_POINTS": False,
            "REPORT": str(tmp_path / "l.html"),
        },
        feedback=log,
    )
    assert "roll@1" in open(result["REPORT"]).read()
    assert max(truth_rms(path, paths, ids).values()) < 0.5


def test_tie_points_alone_with_priors(pushbroom_provider, scene, tmp_path, log, figures):
    """No control points: refused with 'auto' or without priors; with named free look-angle constants and
    weak priors holding the datum, the tie points alone remove the injected across-track differences
    between the images (+-20 urad): the adjusted psi_y constants agree (truth: all equal). The along-track
    ones (psi_x, injected equal) move the heights of all points together: the priors hold them."""
    path = str(tmp_path / "ties_only.gpkg")
    ids, _ = make_tie_block(scene, path)
    Block(path).save_control_points(Observations(), replace_fewer=True)
    for params in ({}, {"FREE": "look:0"}):
        with pytest.raises(QgsProcessingException, match="no control points.*PRIORS"):
            processing.run("pushbroom:bundleadjust", {"BLOCK": path, "VARIANCE_COMPONENTS": False, **params})
    with pytest.raises(QgsProcessingException, match="pattern=sigma"):
        processing.run("pushbroom:bundleadjust", {"BLOCK": path, "FREE": "look:0", "PRIORS": "look:0"})
    before = {i: Block(path).model(i).orientation.corrections.look[1, 0] for i in ids.values()}
    result = processing.run(
        "pushbroom:bundleadjust",
        {"BLOCK": path, "FREE": "look:0", "PRIORS": "look:0=1e-4", "VARIANCE_COMPONENTS": False},
        feedback=log,
    )
    assert 0.25 < result["SIGMA0"] < 0.6  # 0.2 px noise against the a priori 0.5 px
    after = {i: Block(path).model(i).orientation.corrections.look[1, 0] for i in ids.values()}
    figures.report("psi_y constants by image id, before", before, "rad")
    figures.report("psi_y constants by image id, after", after, "rad")
    assert np.ptp(list(before.values())) == pytest.approx(4e-5)
    assert np.ptp(list(after.values())) < 1e-6
