"""The graphical-modeler model resources/models/pushbroom_pipeline.model3: it is what
scripts/build_pipeline_model.py builds, and it runs end to end through qgis_process, its tiled steps
on a Dask LocalCluster of 2 worker processes, on the small simulated triplet (5 control, 2 check
points) with its results checked against the simulator's truth through GDAL."""

import csv
import importlib.util
import json
import pathlib

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingException, QgsProcessingModelAlgorithm

import pushbroom
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.simulation.terrain import CLASSES

REPO = pathlib.Path(pushbroom.__file__).resolve().parent
MODEL = REPO / "resources" / "models" / "pushbroom_pipeline.model3"
DENSE_MODEL = REPO / "resources" / "models" / "pushbroom_pipeline_dense.model3"
#: child id -> algorithm: one child per step, and `checkimage`, the orthoimage that checks IMAGE_NAME early
STEPS = {
    **{
        k: k
        for k in (
            "createblock",
            "matchpoints",
            "selecttiepoints",
            "importpoints",
            "bundleadjust",
            "intersectpoints",
            "interpolatedem",
            "orthorectify",
            "assessaccuracy",
        )
    },
    "checkimage": "orthorectify",
}
OUTPUTS = {
    "createblock:block": "block.gpkg",
    "bundleadjust:report": "adjustment.html",
    "intersectpoints:pointcloud": "points.las",
    "interpolatedem:dem": "dem.tif",
    "orthorectify:orthoimage": "ortho.tif",
    "assessaccuracy:report": "report.html",
    "assessaccuracy:table": "accuracy.csv",
    "assessaccuracy:dh": "dh.tif",
}
#: the dense variant's further children and outputs: the DTM of its DSM, the true orthoimage's occlusion mask
DENSE_STEPS = {**STEPS, "extractdtm": "extractdtm"}
DENSE_OUTPUTS = {
    **OUTPUTS,
    "orthorectify:occlusions": "occlusions.tif",
    "extractdtm:dtm": "dtm.tif",
    "extractdtm:dhm": "dhm.tif",
}


def builder():
    spec = importlib.util.spec_from_file_location("build_pipeline_model", REPO / "scripts" / "build_pipeline_model.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load(path):
    model = QgsProcessingModelAlgorithm()
    assert model.fromFile(str(path)), path
    return model


def test_model_file_is_what_the_script_builds(pushbroom_provider, tmp_path):
    model = load(MODEL)
    assert (model.name(), model.group()) == ("Pushbroom pipeline", "Pushbroom")
    assert set(model.childAlgorithms()) == set(STEPS)
    assert all(c.algorithmId() == f"pushbroom:{STEPS[k]}" for k, c in model.childAlgorithms().items())
    ok, problems = model.validate()
    assert ok, problems
    assert {d.name() for d in model.destinationParameterDefinitions()} >= set(OUTPUTS)
    assert builder().build().toFile(str(tmp_path / "built.model3"))
    assert model.toVariant() == load(tmp_path / "built.model3").toVariant(), "run scripts/build_pipeline_model.py"
    dense = load(DENSE_MODEL)
    assert dense.name() == "Pushbroom pipeline (dense)" and set(dense.childAlgorithms()) == set(DENSE_STEPS)
    assert dense.validate()[0] and {d.name() for d in dense.destinationParameterDefinitions()} >= set(DENSE_OUTPUTS)
    assert builder().build(dense=True).toFile(str(tmp_path / "dense.model3"))
    assert dense.toVariant() == load(tmp_path / "dense.model3").toVariant(), "run scripts/build_pipeline_model.py"
    sources = {k: c.parameterSources() for k, c in dense.childAlgorithms().items()}
    assert sources["matchpoints"]["STRATEGY"][0].staticValue() == 2
    assert sources["interpolatedem"]["METHOD"][0].staticValue() == 1
    assert sources["interpolatedem"]["FALLBACK"][0].staticValue() is False
    assert sources["interpolatedem"]["FILL"][0].staticValue() == 10.0
    # the DTM needs Bulldozer: it runs last, after every other output is written
    last = {d.childId for d in dense.childAlgorithms()["extractdtm"].dependencies()}
    assert {"orthorectify", "assessaccuracy"} <= last
    assert {p.name() for p in dense.parameterDefinitions()}.isdisjoint({"STEP", "MAX_EDGE"})


def test_cheap_inputs_are_checked_before_the_matching(pushbroom_provider, small_scene, tmp_path, log):
    """QGIS checks a model's inputs only by type: the control points are imported, and the image to
    orthorectify is looked up, before the matching, not after the whole chain (before: the last step)."""
    for path in (MODEL, DENSE_MODEL):
        assert {"importpoints", "checkimage"} <= set(load(path).dependsOnChildAlgorithms("matchpoints"))
    block = tmp_path / "block.gpkg"
    parameters = {
        "IMAGES": [small_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")],
        "HEIGHT": 300,
        "POINTS": small_scene["points"],
        "MEAS_SUFFIX": "_meas",
        "REFERENCE": small_scene["dsm"],
        "IMAGE_NAME": "SPOT",
        "createblock:block": str(block),
        **{key: str(tmp_path / name) for key, name in OUTPUTS.items() if key != "createblock:block"},
    }
    with pytest.raises(QgsProcessingException):
        processing.run(load(MODEL), parameters, feedback=log)
    assert any("the block has no image 'SPOT'" in m for m in log.errors)  # the reason, named
    info = Block(block).info()
    assert "mass_points" not in info  # refused before the matching ran
    assert len(Block(block).control_points().points)  # the points were imported first


def warped(path, like, resampling="bilinear"):
    """`path` resampled by GDAL onto the grid of the raster `like` (nodata NaN)."""
    ds = gdal.Open(str(like))
    gt, cols, rows = ds.GetGeoTransform(), ds.RasterXSize, ds.RasterYSize
    out = gdal.Warp(
        "",
        str(path),
        format="MEM",
        dstSRS=ds.GetProjection(),
        outputType=gdal.GDT_Float32,
        outputBounds=(gt[0], gt[3] + rows * gt[5], gt[0] + cols * gt[1], gt[3]),
        width=cols,
        height=rows,
        resampleAlg=resampling,
        dstNodata=np.nan,
    )
    return out.ReadAsArray()


def band(path):
    """The first band as float, nodata NaN."""
    ds = gdal.Open(str(path))
    values = ds.GetRasterBand(1).ReadAsArray().astype(float)
    values[values == ds.GetRasterBand(1).GetNoDataValue()] = np.nan
    return values


@pytest.fixture(scope="module")
def pipeline(small_scene, qgis_process, tmp_path_factory):
    """The model run once through qgis_process (by its path, as make demo runs it), its tiled steps on a Dask
    LocalCluster of 2 worker processes: (results, folder)."""
    out = tmp_path_factory.mktemp("pipeline")
    with open(small_scene["points"], newline="") as f:
        ids = [r["id"] for r in csv.DictReader(f)]
    images = [f"IMAGES={small_scene['images'][n]['imagery']}" for n in ("HRG", "HRS1", "HRS2")]
    result = qgis_process(
        "run",
        str(MODEL),
        "--",
        *images,
        "HEIGHT=300",
        f"POINTS={small_scene['points']}",
        f"CHECK_IDS={','.join(ids[5:])}",
        "MEAS_SUFFIX=_meas",
        f"REFERENCE={small_scene['dsm']}",
        f"CLASS_RASTER={small_scene['classes']}",
        "EXECUTION=2",
        "THREADS=2",
        *(f"{k}={out / v}" for k, v in OUTPUTS.items()),
    )
    assert "on a Dask local cluster of 2 worker processes" in json.dumps(result["log"])
    return result["results"], out


@pytest.mark.slow
def test_pipeline_writes_every_output(pipeline):
    results, out = pipeline
    for key, name in OUTPUTS.items():
        assert results[key] == str(out / name) and (out / name).stat().st_size > 0, key
    for name in ("dem.tif", "ortho.tif", "dh.tif"):
        ds = gdal.Open(str(out / name))
        assert ds.GetRasterBand(1).GetBlockSize()[1] > 1 and ds.GetRasterBand(1).GetOverviewCount() > 0  # tiled
        assert ds.GetRasterBand(1).GetNoDataValue() is not None
        assert "UTM zone 16N" in ds.GetProjection()


@pytest.mark.slow
@pytest.mark.ratchet
def test_pipeline_dem_against_the_true_dsm(pipeline, small_scene, figures):
    """The DEM against the true DSM resampled by GDAL; the dh raster of pushbroom:assessaccuracy
    (reference averaged over the DEM cells) agrees with it."""
    _, out = pipeline
    dem = band(out / "dem.tif")
    dh = dem - warped(small_scene["dsm"], out / "dem.tif")
    defined = np.isfinite(dh)
    figures.report("DEM cells defined", 100 * defined.mean(), "%")
    figures.report("DEM - true DSM, median |dh|", np.median(np.abs(dh[defined])), "m")
    figures.report("DEM - true DSM, median dh", np.median(dh[defined]), "m")
    assert defined.mean() > 0.25
    assert np.median(np.abs(dh[defined])) < 4.0 and abs(np.median(dh[defined])) < 2.0
    reported = band(out / "dh.tif")
    both = defined & np.isfinite(reported)
    assert both.sum() > 0.95 * defined.sum()
    assert abs(np.median(reported[both]) - np.median(dh[both])) < 0.3


@pytest.mark.slow
@pytest.mark.ratchet
def test_pipeline_orthoimage_matches_the_true_orthoimage(pipeline, small_scene, figures):
    """The HRG orthoimage against the simulator's true orthoimage resampled by GDAL onto its grid."""
    _, out = pipeline
    ortho = band(out / "ortho.tif")
    truth = warped(small_scene["orthoimage"], out / "ortho.tif")
    both = np.isfinite(ortho) & np.isfinite(truth)
    r = np.corrcoef(ortho[both], truth[both])[0, 1]
    figures.report("orthoimage cells compared", both.sum())
    figures.report("orthoimage, correlation with the true orthoimage", r)
    assert both.sum() > 0.5 * np.isfinite(ortho).sum() and r > 0.8


@pytest.mark.slow
def test_pipeline_reports_hold_the_tables(pipeline):
    _, out = pipeline
    adjustment = (out / "adjustment.html").read_text()
    assert "Check points (Kornus et al. 2006, Table 3)" in adjustment and "P006" in adjustment and "P007" in adjustment
    report = (out / "report.html").read_text()
    for title in (
        "dh [m] of the object points - reference: per point group",
        "dh [m] of the DEM cells - reference: per class",
        "nested classes (Zhang and Gruen 2004, Tables 2-3)",
    ):
        assert title in report, title
    with open(out / "accuracy.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    dem_all = [r for r in rows if r["data"] == "DEM cells" and r["table"].startswith("all")]
    dem = band(out / "dem.tif")
    assert len(dem_all) == 1 and 0 < int(dem_all[0]["n"]) <= np.isfinite(dem).sum()
    classes = {r["label"] for r in rows if r["table"] == "per class"}
    assert {"bare fields", "forest"} <= classes


def dem_per_class(out):
    """{class: (n, RMS)} of the DEM cells in assessaccuracy's table."""
    with open(out / "accuracy.csv", newline="") as f:
        return {
            r["label"]: (int(r["n"]), float(r["rms"]))
            for r in csv.DictReader(f)
            if r["data"] == "DEM cells" and r["table"] == "per class"
        }


@pytest.mark.slow
def test_dense_pipeline_without_a_height(pipeline, small_scene, qgis_process, tmp_path, figures):
    """The dense variant on the same scene with no DEM and no height (createblock finds the terrain's), its DEM
    per class next to the region-growing model's."""
    with open(small_scene["points"], newline="") as f:
        ids = [r["id"] for r in csv.DictReader(f)]
    images = [f"IMAGES={small_scene['images'][n]['imagery']}" for n in ("HRG", "HRS1", "HRS2")]
    result = qgis_process(
        "run",
        str(DENSE_MODEL),
        "--",
        *images,
        f"POINTS={small_scene['points']}",
        f"CHECK_IDS={','.join(ids[5:])}",
        "MEAS_SUFFIX=_meas",
        f"REFERENCE={small_scene['dsm']}",
        f"CLASS_RASTER={small_scene['classes']}",
        "THREADS=2",
        *(f"{k}={tmp_path / v}" for k, v in DENSE_OUTPUTS.items()),
    )
    log = json.dumps(result["log"])
    assert all((tmp_path / v).exists() for v in DENSE_OUTPUTS.values())
    assert "finding the terrain height by matching" in log and "dense matching:" in log
    dense, region_growing = dem_per_class(tmp_path), dem_per_class(pipeline[1])
    figures.table(
        "10 m DEM against the true DSM per class: the dense model, no height / the region-growing model",
        [
            {
                "class": k,
                "dense cells": dense[k][0],
                "dense RMS m": dense[k][1],
                "region growing cells": region_growing[k][0],
                "region growing RMS m": region_growing[k][1],
            }
            for k in dense
            if k in region_growing
        ],
    )
    dem = band(tmp_path / "dem.tif")
    dh = dem - warped(small_scene["dsm"], tmp_path / "dem.tif")
    figures.report(
        "dense model: DEM cells defined, median |dh|",
        [100 * np.isfinite(dh).mean(), np.median(np.abs(dh[np.isfinite(dh)]))],
        "%, m",
    )
    assert np.isfinite(dh).mean() > 0.6 and np.median(np.abs(dh[np.isfinite(dh)])) < 4.0  # filled within 10 cells
    # region growing measures only the cells it matches best (a third of dense's grass): the two are compared on
    # the cells both DEMs hold, by class of the true land cover
    dh_region_growing = warped(pipeline[1] / "dem.tif", tmp_path / "dem.tif") - warped(
        small_scene["dsm"], tmp_path / "dem.tif"
    )
    classes = warped(small_scene["classes"], tmp_path / "dem.tif", "near")
    both = np.isfinite(dh) & np.isfinite(dh_region_growing)
    rms = {
        name: [float(np.sqrt(np.mean(d[both & (classes == code)] ** 2))) for d in (dh, dh_region_growing)]
        for code, name in CLASSES.items()
        if name in ("bare fields", "grass/crops", "forest")
    }
    figures.table(
        "10 m DEM RMS on the cells both models hold: dense (no height) / region growing",
        [{"class": k, "dense RMS m": v[0], "region growing RMS m": v[1]} for k, v in rms.items()],
    )
    assert all(dense[k][0] > region_growing[k][0] for k in rms), dense  # more cells measured
    # where both measure, dense is about as good: its LSM refinement is region growing's, its DEM the per-cell
    # median of single-pixel points where region growing's TIN averages over its STEP (the bound of before)
    assert all(v[0] < 1.25 * v[1] for v in rms.values()), rms
    # the DTM of the dense DSM: nearer the true DTM than the DSM is, where the DSM stands above the ground
    true_dtm = warped(small_scene["dtm"], tmp_path / "dem.tif")
    dtm, dhm = band(tmp_path / "dtm.tif"), band(tmp_path / "dhm.tif")
    np.testing.assert_allclose(dhm[np.isfinite(dem)], (dem - dtm)[np.isfinite(dem)], atol=1e-3)
    departure = {}
    for code, name in CLASSES.items():
        if name in ("bare fields", "forest", "city/buildings"):
            cells = (classes == code) & np.isfinite(dem) & np.isfinite(dtm)
            departure[name] = [float(np.sqrt(np.mean((g[cells] - true_dtm[cells]) ** 2))) for g in (dtm, dem)]
    figures.table(
        "dense model: RMS against the true DTM, of its DTM and of its DSM",
        [{"class": k, "DTM RMS m": v[0], "DSM RMS m": v[1]} for k, v in departure.items()],
    )
    assert departure["city/buildings"][0] < 0.8 * departure["city/buildings"][1], departure
    assert departure["forest"][0] < departure["forest"][1], departure
    codes = gdal.Open(str(tmp_path / "occlusions.tif")).ReadAsArray()
    assert set(np.unique(codes)) <= {0, 1, 255} and (codes == 0).sum() > 0
