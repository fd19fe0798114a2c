"""pushbroom:intersectpoints on a block of the simulated SPOT 5 triplet whose mass and tie points are
made from ground points on the true DSM (projected with the block's models: the intersection must
give them back)."""

import os

import numpy as np
import pytest
from osgeo import gdal, ogr
from qgis import processing
from qgis.core import (
    QgsPointCloudLayer,
    QgsProcessingContext,
    QgsProcessingException,
    QgsProcessingFeedback,
    QgsProject,
    QgsVectorLayer,
)

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching.points import OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.surface.pointcloud import laspy_module
from tests.helpers.osr_oracle import utm


@pytest.fixture(scope="module")
def triplet(small_scene, tmp_path_factory):
    images = Block.open_images([small_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    dsm = read_dem(small_scene["dsm"])
    return {
        "images": images,
        "dsm": dsm,
        "folder": tmp_path_factory.mktemp("intersect"),
        "height": float(np.nanmean(dsm.heights)),
    }


def make_block(triplet, name, kinds=("mass_points",)):
    """A block with points of `kinds`: ground points on the DSM seen in all three images; ids 0..199
    three-ray (group 3), 200..299 only in HRG and HRS1 (group 1). Returns (path, lon, lat, h)."""
    path = str(triplet["folder"] / name)
    Block.create(path, triplet["images"], height=triplet["height"], overwrite=True)
    ids = {r["name"]: r["id"] for r in Block(path).images()}
    models = {n: Block(path).model(i) for n, i in ids.items()}
    rng = np.random.default_rng(1)
    cols, rows = models["HRG"].size
    lon, lat, h = models["HRG"].image_to_dem(
        rng.uniform(150, cols - 150, 300), rng.uniform(100, rows - 100, 300), triplet["dsm"]
    )
    obs = []
    for name in ("HRG", "HRS1", "HRS2"):
        col, row = models[name].ground_to_image(lon, lat, h)
        keep = np.arange(300) < (300 if name != "HRS2" else 200)
        o = np.zeros(keep.sum(), OBS_DTYPE)
        o["point_id"], o["image_id"], o["col"], o["row"] = np.flatnonzero(keep), ids[name], col[keep], row[keep]
        obs.append(o)
    obs = np.concatenate(obs)
    obs = obs[np.lexsort((obs["image_id"], obs["point_id"]))]
    pts = np.zeros(300, POINT_DTYPE)
    pts["id"] = np.arange(300)
    pts["group"] = np.where(pts["id"] < 200, 3, 1)
    pts["rho_min"] = rng.uniform(0.7, 1.0, 300)
    for kind in kinds:
        Block(path).store_points(MultiPoints(pts, obs), kind)
    return path, lon, lat, h


class CancelOnProgress(QgsProcessingFeedback):
    """Cancels when the run first reports progress (as a user pressing Cancel while it runs)."""

    def __init__(self):
        super().__init__()
        self.progressChanged.connect(lambda _: self.cancel())


def run(parameters, context=None, feedback=None):
    return processing.run(
        "pushbroom:intersectpoints",
        parameters,
        context=context or QgsProcessingContext(),
        feedback=feedback or QgsProcessingFeedback(),
    )


def test_las_in_the_blocks_utm_zone(pushbroom_provider, triplet, tmp_path, log):
    path, lon, lat, h = make_block(triplet, "las.gpkg")
    feedback = log
    result = run({"BLOCK": path, "OUTPUT": str(tmp_path / "cloud.las")}, feedback=feedback)
    assert result["COUNT"] == 300
    laspy = laspy_module()
    las = laspy.read(result["OUTPUT"])
    wkt = [v.string for v in las.header.vlrs if isinstance(v, laspy.vlrs.known.WktCoordinateSystemVlr)]
    assert Block(path).info()["default_crs"] == "EPSG:32616" and "UTM zone 16N" in wkt[0]
    order = np.argsort(np.asarray(las["point_id"]))
    x, y = utm(lon, lat, 32616)
    np.testing.assert_allclose(np.asarray(las.x)[order], x, atol=0.0011)  # 1 mm resolution + intersection
    np.testing.assert_allclose(np.asarray(las.y)[order], y, atol=0.0011)
    np.testing.assert_allclose(np.asarray(las.z)[order], h, atol=0.0011)
    group, rays, sigma_h = (np.asarray(las[k])[order] for k in ("group", "rays", "sigma_h"))
    np.testing.assert_array_equal(group, np.where(np.arange(300) < 200, 3, 1))
    np.testing.assert_array_equal(rays, np.where(np.arange(300) < 200, 3, 2))
    assert np.median(sigma_h[:200]) < np.median(sigma_h[200:])  # three rays give better heights
    log = "\n".join(feedback.messages)
    assert "converged 300" in log and "sigma_H" in log
    summary = [line.split() for line in log.splitlines() if line.split()[:1] in (["1"], ["3"])]
    assert [(s[0], s[1]) for s in summary] == [("1", "100"), ("3", "200")]
    assert float(summary[1][5]) == pytest.approx(np.median(sigma_h[:200]), rel=1e-3)
    assert "intersectpoints" in [r["step"] for r in Block(path).run_log()]


def test_points_coloured_from_the_first_image_that_observes_them(pushbroom_provider, triplet, tmp_path):
    """The LAS colour fields (point format 7): every point's HRG pixel (all 300 are in HRG, the block's first
    image), stretched between the band's mean -+ 2.5 sigma to 16 bits, grey: read here with GDAL at the pixel of
    the point's HRG position, the statistics computed here with numpy; nothing written beside the images."""
    path, lon, lat, h = make_block(triplet, "colour.gpkg")
    hrg = next(r for r in Block(path).images() if r["name"] == "HRG")
    folder = os.path.dirname(hrg["image_path"])
    before = sorted(os.listdir(folder))
    result = run({"BLOCK": path, "OUTPUT": str(tmp_path / "colour.laz")})
    assert sorted(os.listdir(folder)) == before  # nothing written beside the images (no .aux.xml statistics)
    las = laspy_module().read(result["OUTPUT"])
    assert las.header.point_format.id == 7
    order = np.argsort(np.asarray(las["point_id"]))
    red, green, blue = (np.asarray(las[k])[order] for k in ("red", "green", "blue"))
    assert np.array_equal(red, green) and np.array_equal(red, blue)  # a one-band image: grey
    col, row = Block(path).model(hrg["id"]).ground_to_image(lon, lat, h)
    ds = gdal.Open(hrg["image_path"])
    image = ds.GetRasterBand(1).ReadAsArray().astype(float)  # under 1024 px a side: the statistics are the image's
    lo, hi = max(image.min(), image.mean() - 2.5 * image.std()), min(image.max(), image.mean() + 2.5 * image.std())
    pixels = image[np.floor(row).astype(int), np.floor(col).astype(int)]
    expected = np.rint(np.clip((pixels - lo) / (hi - lo), 0, 1) * 65535)
    np.testing.assert_array_equal(red, expected)
    assert red.std() > 1000  # the scene's texture, not one value
    plain = run({"BLOCK": path, "COLOUR": False, "OUTPUT": str(tmp_path / "plain.las")})
    assert laspy_module().read(plain["OUTPUT"]).header.point_format.id == 6


def test_ept_index_loaded_as_a_coloured_point_cloud(pushbroom_provider, triplet, tmp_path):
    """EPT: the LAZ's EPT index, loaded on completion as a point cloud layer (QGIS's ept provider) with its colours;
    a GeoPackage output has none."""
    path, _, _, _ = make_block(triplet, "ept.gpkg")
    context = QgsProcessingContext()
    context.setProject(QgsProject.instance())
    folder = str(tmp_path / "cloud.ept")
    result = run({"BLOCK": path, "OUTPUT": str(tmp_path / "cloud.laz"), "EPT": folder}, context)
    assert result["EPT"] == folder and os.path.exists(os.path.join(folder, "ept.json"))
    (layer_id,) = context.layersToLoadOnCompletion()
    layer = context.temporaryLayerStore().mapLayer(layer_id)
    assert isinstance(layer, QgsPointCloudLayer) and layer.pointCount() == 300 and layer.renderer().type() == "rgb"
    with pytest.raises(QgsProcessingException, match="EPT index is made from a LAS or LAZ"):
        run({"BLOCK": path, "OUTPUT": str(tmp_path / "cloud.gpkg"), "EPT": str(tmp_path / "g.ept")})


def test_geopackage_of_tie_points_in_a_given_crs(pushbroom_provider, triplet, tmp_path):
    path, lon, lat, h = make_block(triplet, "gpkg.gpkg", kinds=("tie_points",))
    context = QgsProcessingContext()
    result = run({"BLOCK": path, "POINTS": 1, "CRS": "EPSG:32617", "OUTPUT": str(tmp_path / "cloud.gpkg")}, context)
    layer = QgsVectorLayer(result["LAYER"], "points", "ogr")
    assert layer.isValid() and layer.featureCount() == 300 and layer.crs().authid() == "EPSG:32617"
    assert result["LAYER"] in context.layersToLoadOnCompletion()
    ds = ogr.Open(result["OUTPUT"])
    got = sorted((f["point_id"], f.GetGeometryRef().GetX(), f.GetGeometryRef().GetZ()) for f in ds.GetLayer(0))
    x, _ = utm(lon, lat, 32617)
    np.testing.assert_allclose([g[1] for g in got], x, atol=0.001)
    np.testing.assert_allclose([g[2] for g in got], h, atol=0.001)


def test_clear_errors_and_cancel(pushbroom_provider, triplet, tmp_path):
    path, *_ = make_block(triplet, "errors.gpkg", kinds=("tie_points",))
    with pytest.raises(QgsProcessingException, match="no mass points.*matchpoints"):
        run({"BLOCK": path, "OUTPUT": str(tmp_path / "a.las")})
    with pytest.raises(QgsProcessingException, match=r"\.las, \.laz or \.gpkg"):
        run({"BLOCK": path, "POINTS": 1, "OUTPUT": str(tmp_path / "a.xyz")})
    cancelled = QgsProcessingFeedback()
    cancelled.cancel()
    for feedback in (CancelOnProgress(), cancelled):
        with pytest.raises(QgsProcessingException, match="cancel"):
            run({"BLOCK": path, "POINTS": 1, "OUTPUT": str(tmp_path / "b.las")}, feedback=feedback)
    assert not list(tmp_path.iterdir())
