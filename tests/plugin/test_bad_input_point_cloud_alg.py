"""pushbroom:interpolatedem on bad point clouds (issue 19), in Processing and through qgis_process: 100
identical points (before: Qhull's "use option 'Qz'"), a LAS without a CRS and a GeoPackage layer without SRS
(before: PROJ's text), degrees labelled UTM (before: "raise the maximum edge"); the point cloud CRS
parameter reads a file without a CRS."""

import numpy as np
import pytest
from qgis import processing

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.surface.pointcloud import write_gpkg
from tests.helpers.bad_inputs import las, processing_error

UTM31 = 32631
UTM31_WKT = srs(UTM31).ExportToWkt()


def cloud(n=400):
    """n points over 1 km near Mont Ventoux, UTM 31N metres."""
    return np.random.default_rng(3).uniform((650_000, 4_890_000, 300), (651_000, 4_891_000, 400), (n, 3)).T


def test_identical_points(pushbroom_provider, tmp_path):
    path = las(
        tmp_path / "same.las", np.full(100, 650_000.0), np.full(100, 4_890_000.0), np.full(100, 400.0), UTM31_WKT
    )
    message = processing_error("pushbroom:interpolatedem", {"INPUT": path, "OUTPUT": str(tmp_path / "dem.tif")})
    # what is wrong with the points and what a TIN needs, in Pushbroom's words, not Qhull's
    assert (
        "the 100 points of the point cloud are all at one position (x 650000.000, y 4890000.000): a TIN needs "
        "at least 3 points that are not on one line" in message
    )
    assert "Qz" not in message and "QH" not in message  # no Qhull text left


def test_a_cloud_without_crs_and_the_point_cloud_crs_parameter(pushbroom_provider, tmp_path):
    x, y, z = cloud()
    path = las(tmp_path / "nocrs.las", x, y, z)
    gpkg = str(tmp_path / "nosrs.gpkg")
    write_gpkg(gpkg, x, y, z, {}, None)
    for source, why in (
        (path, "no WKT or EPSG GeoKey VLR"),
        (gpkg, "its CRS 'Undefined geographic SRS' is a local or undefined one"),
    ):
        message = processing_error("pushbroom:interpolatedem", {"INPUT": source, "OUTPUT": str(tmp_path / "dem.tif")})
        # the file, what it lacks, and the parameter that supplies it; no PROJ text
        assert f"the point cloud {source} has no coordinate reference system ({why}" in message
        assert "give the CRS its x, y are in (the point cloud CRS parameter)" in message  # what to do
        assert "PROJ" not in message  # no PROJ text left
    result = processing.run(
        "pushbroom:interpolatedem",
        {"INPUT": path, "INPUT_CRS": f"EPSG:{UTM31}", "CELL": 20.0, "OUTPUT": str(tmp_path / "dem.tif")},
    )
    assert result["POINTS"] == 400  # the CRS given, every point is in the TIN


def test_degrees_labelled_utm(pushbroom_provider, tmp_path):
    x, y, z = cloud()
    path = las(tmp_path / "degrees.las", 5.27 + (x - x.min()) * 1e-5, 44.17 + (y - y.min()) * 1e-5, z, UTM31_WKT)
    message = processing_error("pushbroom:interpolatedem", {"INPUT": path, "OUTPUT": str(tmp_path / "dem.tif")})
    # the diagnosis instead of the symptom ("raise the maximum edge")
    assert "these look like longitude/latitude degrees labelled with a projected CRS" in message
    assert "maximum edge" not in message  # not the old, misleading advice


@pytest.mark.slow
def test_qgis_process_degrees_labelled_utm(qgis_process, tmp_path):
    x, y, z = cloud()
    path = las(tmp_path / "degrees.las", 5.27 + (x - x.min()) * 1e-5, 44.17 + (y - y.min()) * 1e-5, z, UTM31_WKT)
    with pytest.raises(RuntimeError) as err:
        qgis_process("run", "pushbroom:interpolatedem", "--", f"INPUT={path}", f"OUTPUT={tmp_path / 'dem.tif'}")
    # what the user reads on the terminal: the file, the diagnosis and the remedy, no traceback
    assert f"the point cloud {path} spans only" in str(err.value)
    assert "EPSG:4326 for degrees" in str(err.value) and "Traceback" not in str(err.value)  # the remedy
