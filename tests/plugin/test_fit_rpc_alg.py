"""pushbroom:fitrpc on a block made from a small simulated SPOT 5 triplet: _RPC.TXT files beside the
image rasters (read by GDAL, matching the block's models) or in a folder, the overwrite rule, and
clear errors."""

import shutil

import numpy as np
import pytest
from osgeo import gdal, ogr
from qgis import processing
from qgis.core import QgsProcessingException, QgsProcessingFeedback

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.sensors.rpc import RpcModel
from pushbroom.algorithms.sensors.rpc_fit import fit_rpc
from pushbroom.algorithms.sensors.rpc_io import write_rpb

gdal.UseExceptions()
NAMES = ("HRG", "HRS1", "HRS2")


@pytest.fixture(scope="module")
def scene(small_scene):
    """(folder, paths, mean DSM height) of the small scene (tests copy the folder before writing)."""
    import pathlib

    height = float(np.nanmean(read_dem(small_scene["dsm"]).heights))
    return pathlib.Path(small_scene["folder"]), small_scene, height


@pytest.fixture
def triplet_block(scene, tmp_path):
    """A block of the triplet whose image rasters lie in tmp_path (a copy of the scene)."""
    folder, _, height = scene
    copy = shutil.copytree(folder, tmp_path / "scene")
    path = tmp_path / "block.gpkg"
    Block.create(path, Block.open_images([copy / n / "IMAGERY.TIF" for n in NAMES]), height=height)
    return str(path), copy


def run_log_steps(path):
    ds = ogr.Open(path)
    return [f["step"] for f in ds.GetLayerByName("run_log")]


def test_fitrpc_writes_rpc_txt_beside_each_raster_and_gdal_reads_it(
    pushbroom_provider, triplet_block, tmp_path, figures
):
    path, scene_copy = triplet_block
    result = processing.run("pushbroom:fitrpc", {"BLOCK": path, "REPORT": str(tmp_path / "fit.html")})
    expected = [str(scene_copy / n / "IMAGERY_RPC.TXT") for n in NAMES]
    assert sorted(result["FILES"]) == sorted(expected)
    rows = {r["name"]: r for r in Block(path).images()}
    terrain = Block(path).height_range()
    rng = np.random.default_rng(5)
    for name in NAMES:
        raster = scene_copy / name / "IMAGERY.TIF"
        ds = gdal.Open(str(raster))
        fields = ds.GetMetadata("RPC")
        assert fields, f"GDAL reads no RPC for {raster}"
        h_off, h_scale = float(fields["HEIGHT_OFF"]), float(fields["HEIGHT_SCALE"])
        assert h_off - h_scale < terrain[0] and h_off + h_scale > terrain[1]  # the terrain range and a margin
        model = Block(path).model(rows[name]["id"])
        col, row = rng.uniform(0, model.size[0], 200), rng.uniform(0, model.size[1], 200)
        h = rng.uniform(*terrain, 200)
        lon, lat = model.image_to_ground(col, row, h)
        out, ok = gdal.Transformer(ds, None, ["METHOD=RPC"]).TransformPoints(1, np.column_stack([lon, lat, h]))
        out = np.array(out)
        err = max(np.abs(out[:, 0] - col).max(), np.abs(out[:, 1] - row).max())
        figures.report(f"{name}: GDAL on the written _RPC.TXT vs the block's model, max", err, "px")
        assert all(ok) and err < 0.02
    page = (tmp_path / "fit.html").read_text()
    assert all(n in page for n in NAMES) and "validation" in page
    assert run_log_steps(path)[-1] == "fitrpc"
    # the block's own models are still the DIMAP ones (the RPC beside the raster does not replace them)
    assert sensors.orientation_source(scene_copy / "HRG" / "IMAGERY.TIF").endswith("METADATA.DIM")

    before = (scene_copy / "HRG" / "IMAGERY_RPC.TXT").read_text()
    with pytest.raises(QgsProcessingException, match="exists already.*overwrite"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "MIN_HEIGHT": 0.0, "MAX_HEIGHT": 3000.0})
    assert (scene_copy / "HRG" / "IMAGERY_RPC.TXT").read_text() == before
    processing.run(
        "pushbroom:fitrpc", {"BLOCK": path, "IMAGE": "HRG", "MIN_HEIGHT": 0.0, "MAX_HEIGHT": 3000.0, "OVERWRITE": True}
    )
    fields = gdal.Open(str(scene_copy / "HRG" / "IMAGERY.TIF")).GetMetadata("RPC")
    assert (float(fields["HEIGHT_OFF"]), float(fields["HEIGHT_SCALE"])) == (1500.0, 1500.0)


def test_fitrpc_one_image_into_a_folder(pushbroom_provider, triplet_block, tmp_path):
    path, scene_copy = triplet_block
    out = tmp_path / "rpc"
    result = processing.run(
        "pushbroom:fitrpc",
        {
            "BLOCK": path,
            "IMAGE": "HRS1",
            "OUTPUT_FOLDER": str(out),
            "GRID": 6,
            "HEIGHT_LEVELS": 5,
            "MIN_HEIGHT": 100.0,
            "MAX_HEIGHT": 900.0,
        },
    )
    assert result["FILES"] == [str(out / "HRS1_RPC.TXT")] and [p.name for p in out.iterdir()] == ["HRS1_RPC.TXT"]
    assert not (scene_copy / "HRS1" / "IMAGERY_RPC.TXT").exists()
    rpc = sensors.load(out / "HRS1_RPC.TXT")
    model = Block(path).model(next(r["id"] for r in Block(path).images() if r["name"] == "HRS1"))
    assert isinstance(rpc, RpcModel) and rpc.size == model.size  # the normalisation spans the whole image
    assert rpc.height_range == pytest.approx((100.0, 900.0))
    col, row = np.meshgrid(np.linspace(0, model.size[0], 7), np.linspace(0, model.size[1], 7))
    lon, lat = model.image_to_ground(col.ravel(), row.ravel(), 500.0)
    c, r = rpc.ground_to_image(lon, lat, 500.0)
    assert max(np.abs(c - col.ravel()).max(), np.abs(r - row.ravel()).max()) < 0.01


@pytest.fixture
def rpc_image(scene, tmp_path):
    """(raster, supplied RpcModel, height): a copy of HRS2's raster carrying an RPC fitted to its DIMAP model
    in its GeoTIFF metadata, as a Pleiades image carries its own."""
    _, paths, height = scene
    raster = tmp_path / "img.tif"
    shutil.copy(paths["images"]["HRS2"]["imagery"], raster)
    supplied, _ = fit_rpc(sensors.load(paths["images"]["HRS2"]["metadata"]), (height - 600.0, height + 600.0))
    ds = gdal.Open(str(raster), gdal.GA_Update)
    ds.SetMetadata(supplied.to_fields(), "RPC")
    ds = None
    return raster, supplied, height


def gdal_height_offset(raster):
    """HEIGHT_OFF of the RPC GDAL reads with `raster`."""
    return float(gdal.Open(str(raster)).GetMetadata("RPC")["HEIGHT_OFF"])


def rpc_block(raster, height):
    path = str(raster.with_name("rpc_block.gpkg"))
    Block.create(path, Block.open_images([raster]), height=height)
    assert Block(path).images()[0]["model_kind"] == "rpc"
    return path


def test_an_image_with_its_own_rpc_is_not_shadowed_without_overwrite(pushbroom_provider, rpc_image, log):
    """The issue-36 case: fitrpc with its defaults on a block of images that carry their RPC in their GeoTIFF
    metadata wrote <stem>_RPC.TXT beside them, which GDAL reads instead, with no word. Now: refused before
    any fit, nothing written; with OVERWRITE written, and the warning says GDAL now reads the fitted RPC."""
    raster, supplied, height = rpc_image
    path = rpc_block(raster, height)
    with pytest.raises(
        QgsProcessingException,
        match=rf"image img carries its own RPC \(the metadata of {raster}\).*"
        r"Give an output folder \(OUTPUT_FOLDER\), or set OVERWRITE",
    ):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "MIN_HEIGHT": 0.0, "MAX_HEIGHT": 3000.0})
    assert not raster.with_name("img_RPC.TXT").exists() and "fitrpc" not in run_log_steps(path)
    assert gdal_height_offset(raster) == pytest.approx(supplied.coefficients.height_off)
    processing.run(
        "pushbroom:fitrpc",
        {"BLOCK": path, "MIN_HEIGHT": 0.0, "MAX_HEIGHT": 3000.0, "OVERWRITE": True, "GRID": 4, "HEIGHT_LEVELS": 4},
        feedback=log,
    )
    # GDAL reads the fitted cube's heights now, and the user was told so
    assert gdal_height_offset(raster) == 1500.0
    assert [
        w
        for w in log.warnings
        if w.startswith(
            f"GDAL now reads {raster.with_name('img_RPC.TXT')} with {raster} "
            f"instead of the image's own RPC (the metadata of {raster})"
        )
    ]


def test_an_rpc_image_delivered_with_an_rpb_is_refitted_on_overwrite_with_a_warning(pushbroom_provider, rpc_image, log):
    """An RPC image whose RPC came as .RPB (GDAL prefers it to a _RPC.TXT): refused by default; with OVERWRITE
    the fit of the block's RPC is written, and the user is told that GDAL still reads the .RPB."""
    raster, supplied, height = rpc_image
    ds = gdal.Open(str(raster), gdal.GA_Update)
    ds.SetMetadata({}, "RPC")
    ds = None
    write_rpb(supplied, raster.with_name("img.RPB"))
    path = rpc_block(raster, height)
    with pytest.raises(QgsProcessingException, match=rf"carries its own RPC \({raster.with_name('img.RPB')}\)"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path})
    result = processing.run("pushbroom:fitrpc", {"BLOCK": path, "OVERWRITE": True}, feedback=log)
    assert result["FILES"] == [str(raster.with_name("img_RPC.TXT"))]
    assert len(log.warnings) == 1 and "GDAL does not read" in log.warnings[0]
    refit = sensors.load(raster.with_name("img_RPC.TXT"))
    lon, lat = supplied.image_to_ground(np.array([1.0, 150.0, 299.0]), np.array([2.0, 300.0, 598.0]), height)
    assert np.allclose(
        refit.ground_to_image(lon, lat, height), supplied.ground_to_image(lon, lat, height), rtol=0, atol=0.01
    )


def test_an_rpc_image_into_an_output_folder_leaves_the_image_alone(pushbroom_provider, rpc_image, tmp_path):
    raster, supplied, height = rpc_image
    path = rpc_block(raster, height)
    result = processing.run(
        "pushbroom:fitrpc", {"BLOCK": path, "OUTPUT_FOLDER": str(tmp_path / "rpc"), "GRID": 4, "HEIGHT_LEVELS": 4}
    )
    assert result["FILES"] == [str(tmp_path / "rpc" / "img_RPC.TXT")]
    assert gdal.Open(str(raster)).GetFileList() == [str(raster)]  # GDAL still reads the image's own RPC
    assert gdal_height_offset(raster) == pytest.approx(supplied.coefficients.height_off)


def test_fitrpc_errors(pushbroom_provider, triplet_block):
    path, _ = triplet_block
    with pytest.raises(QgsProcessingException, match="image XS is not in the block; it has HRG, HRS1, HRS2"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "IMAGE": "XS"})
    with pytest.raises(QgsProcessingException, match="both the lowest and the highest"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "MIN_HEIGHT": 100.0})
    with pytest.raises(QgsProcessingException, match=r"lowest height of its cube \(500 m\) is the same as the highest"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "MIN_HEIGHT": 500.0, "MAX_HEIGHT": 500.0})
    # a cube in the stratosphere: no terrain on Earth lies there (issue 36: fitted and written without a word)
    with pytest.raises(
        QgsProcessingException,
        match=r"the lowest height of the RPC cube \(MIN_HEIGHT\) of 20000 m "
        r"lies outside the heights of terrain on Earth \(-500 \.\. 9000",
    ):
        processing.run("pushbroom:fitrpc", {"BLOCK": path, "MIN_HEIGHT": 20000.0, "MAX_HEIGHT": 30000.0})
    assert "fitrpc" not in run_log_steps(path)


def test_cancel_writes_nothing(pushbroom_provider, triplet_block):
    path, scene_copy = triplet_block
    feedback = QgsProcessingFeedback()
    feedback.cancel()
    with pytest.raises(QgsProcessingException, match="cancel"):
        processing.run("pushbroom:fitrpc", {"BLOCK": path}, feedback=feedback)
    assert not list(scene_copy.glob("*/*_RPC.TXT")) and "fitrpc" not in run_log_steps(path)


def test_report_compares_rpc_and_rigorous_object_points_of_the_tie_points(
    pushbroom_provider, triplet_block, tmp_path, figures
):
    """With tie points in the block (here: 200 ground points projected into the three images), the
    report gives the RPC minus rigorous differences of Kornus et al. (2006, Table 5); the fit is good to well
    below 1 cm."""
    import re

    from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints

    path, _ = triplet_block
    rows = Block(path).images()
    models = {r["id"]: Block(path).model(r["id"]) for r in rows}
    first = models[rows[0]["id"]]
    rng = np.random.default_rng(2)
    lon, lat = first.image_to_ground(
        rng.uniform(50, first.size[0] - 50, 200), rng.uniform(50, first.size[1] - 50, 200), np.full(200, 300.0)
    )
    pts = np.zeros(200, POINT_DTYPE)
    pts["id"], pts["group"] = np.arange(200), 3
    obs = np.zeros(600, OBS_DTYPE)
    obs["point_id"] = np.repeat(np.arange(200), 3)
    for k, (i, model) in enumerate(models.items()):
        obs["image_id"][k::3] = i
        obs["col"][k::3], obs["row"][k::3] = model.ground_to_image(lon, lat, 300.0)
    Block(path).store_points(MultiPoints(pts, obs), "tie_points")
    processing.run("pushbroom:fitrpc", {"BLOCK": path, "REPORT": str(tmp_path / "fit.html")})
    page = (tmp_path / "fit.html").read_text()
    found = re.search(r"Table 5\): 200 points .* max \|dh\| ([0-9.]+) m", page)
    assert found, page
    figures.report("RPC - rigorous object points of 200 tie points, max |dh|", float(found.group(1)), "m")
    assert float(found.group(1)) < 0.01
