"""The COG option of every algorithm with raster outputs (issue 40): with COG on, each raster output is a valid
Cloud-Optimised GeoTIFF (GDAL's own LAYOUT=COG, tiles and overviews in COG order), and holds the same values,
nodata, metadata and overview count as the plain GeoTIFF the same run writes without it."""

import numpy as np
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingFeedback

from pushbroom.algorithms import crs
from pushbroom.algorithms.surface.geotiff import write_float_raster
from tests.helpers.dem_shift import ORIGIN, UTM, centres, terrain
from tests.helpers.roof_cloud import roof_cloud


def run(algorithm, parameters):
    return processing.run(
        f"pushbroom:{algorithm}", parameters, context=QgsProcessingContext(), feedback=QgsProcessingFeedback()
    )


def assert_cog_like(cog_path, plain_path):
    cog, plain = gdal.Open(cog_path), gdal.Open(plain_path)
    assert cog.GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE") == "COG", cog_path
    assert plain.GetMetadataItem("LAYOUT", "IMAGE_STRUCTURE") != "COG"
    a, b = cog.GetRasterBand(1), plain.GetRasterBand(1)
    assert np.array_equal(a.ReadAsArray(), b.ReadAsArray()) and a.GetNoDataValue() == b.GetNoDataValue()
    assert a.GetOverviewCount() == b.GetOverviewCount() and a.GetDescription() == b.GetDescription()
    assert cog.GetMetadata() == plain.GetMetadata() and cog.GetGeoTransform() == plain.GetGeoTransform()


def test_interpolatedem_writes_every_raster_as_cog(pushbroom_provider, tmp_path):
    las, _, _ = roof_cloud(tmp_path, n=20000)
    outputs = {}
    for cog in (False, True):
        outputs[cog] = run(
            "interpolatedem",
            {
                "INPUT": las,
                "CELL": 2.0,  # 500 x 500 cells: overviews
                "METHOD": 1,
                "FILL": 3,
                "COG": cog,
                "OUTPUT": str(tmp_path / f"dem_{cog}.tif"),
                "PRECISION": str(tmp_path / f"se_{cog}.tif"),
                "COUNT": str(tmp_path / f"n_{cog}.tif"),
                "MASK": str(tmp_path / f"mask_{cog}.tif"),
            },
        )
    for key in ("OUTPUT", "PRECISION", "COUNT", "MASK"):
        assert_cog_like(outputs[True][key], outputs[False][key])
    dem = gdal.Open(outputs[True]["OUTPUT"])  # alive while its band is asked
    assert dem.GetRasterBand(1).GetOverviewCount() > 0


def test_coregisterdem_and_assessaccuracy_write_cog(pushbroom_provider, tmp_path):
    srs = crs.srs(UTM)
    hills = terrain(*centres(ORIGIN, 600, 5.0))
    reference = write_float_raster(str(tmp_path / "ref.tif"), hills, (500_000, 5, 0, 4_800_000, 0, -5), srs)
    dem = write_float_raster(str(tmp_path / "dem.tif"), hills + 1.0, (500_003, 5, 0, 4_800_000, 0, -5), srs)
    for cog in (False, True):
        run("coregisterdem", {"DEM": dem, "REFERENCE": reference, "COG": cog, "OUTPUT": str(tmp_path / f"c_{cog}.tif")})
        run(
            "assessaccuracy",
            {
                "REFERENCE": reference,
                "DEM": dem,
                "COG": cog,
                "REPORT": str(tmp_path / f"r_{cog}.html"),
                "DH": str(tmp_path / f"dh_{cog}.tif"),
            },
        )
    assert_cog_like(str(tmp_path / "c_True.tif"), str(tmp_path / "c_False.tif"))
    assert_cog_like(str(tmp_path / "dh_True.tif"), str(tmp_path / "dh_False.tif"))


def test_orthorectify_writes_cog(pushbroom_provider, small_scene, tmp_path):
    image = small_scene["images"]["HRG"]["imagery"]
    for cog in (False, True):
        run(
            "orthorectify",
            {
                "IMAGE": image,
                "DEM": small_scene["dsm"],
                "CELL_SIZE": 20.0,
                "COG": cog,
                "OUTPUT": str(tmp_path / f"o_{cog}.tif"),
                "OCCLUSIONS": str(tmp_path / f"m_{cog}.tif"),
            },
        )
    assert_cog_like(str(tmp_path / "o_True.tif"), str(tmp_path / "o_False.tif"))
    assert_cog_like(str(tmp_path / "m_True.tif"), str(tmp_path / "m_False.tif"))


def test_simulatescene_writes_its_ground_rasters_as_cog(pushbroom_provider, tmp_path):
    """A 1 km scene, twice from one seed: the ground rasters as COG hold what the plain ones hold; the level-1A
    imagery is the same bytes either way."""
    results = {}
    for cog in (False, True):
        results[cog] = run(
            "simulatescene",
            {"SIZE_KM": 1.0, "POINTS": 0, "COG": cog, "OUTPUT": str(tmp_path / f"scene_{cog}")},
        )
    for key in ("DSM", "DTM", "CLASSES", "ORTHOIMAGE"):
        assert_cog_like(results[True][key], results[False][key])
    for plain, cog in zip(results[False]["IMAGES"], results[True]["IMAGES"]):
        with open(plain, "rb") as a, open(cog, "rb") as b:
            assert a.read() == b.read()
