"""The orthoimage's grid and DEM checked before the work (issue 36): a cell size in the wrong unit, a CRS used far
from the image and a DEM that covers part of the image, on the small simulated scene."""

import numpy as np
import pytest
from osgeo import gdal, ogr

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.ortho import default_grid
from pushbroom.algorithms.ortho.grid import dem_coverage
from pushbroom.algorithms.steps.orthoimage import OrthoParams, orthorectify_image
from tests.helpers.feedback import Feedback


@pytest.fixture(scope="module")
def scene(small_scene):
    image = small_scene["images"]["HRG"]["imagery"]
    return {"paths": small_scene, "dsm": read_dem(small_scene["dsm"]), "image": image, "hrg": sensors.load(image)}


def test_a_cell_size_in_metres_on_a_degree_crs_is_refused(scene):
    # issue 36: CRS=EPSG:4326 with CELL_SIZE=5 made an orthoimage of one cell
    with pytest.raises(
        InputError,
        match=r"a cell size of 5 degrees makes the orthoimage a grid of 1 x 1 cells .*"
        r"is the cell size in metres\?",
    ):
        default_grid(scene["hrg"], scene["dsm"], crs="EPSG:4326", cell_size=5.0)
    grid = default_grid(scene["hrg"], scene["dsm"], crs="EPSG:4326", cell_size=0.0001)  # about 10 m: a grid
    assert min(grid.cols, grid.rows) > 100


def test_a_utm_zone_far_from_the_image_is_refused(scene):
    # issue 36: zone 49N (108 .. 114 E) for a scene at 84 W put the image, mirrored, at a northing of 15.7e6 m
    with pytest.raises(
        InputError,
        match=r"the output CRS WGS 84 / UTM zone 49N is used at longitude 108 \.\. 114, "
        r"latitude 0 \.\. 84, far from the image \(longitude -84\.\d+",
    ):
        default_grid(scene["hrg"], scene["dsm"], crs="EPSG:32649")
    assert default_grid(scene["hrg"], scene["dsm"], crs="EPSG:32617").cols > 100  # the next zone: usable


class StopAfterTheWarning(Feedback):
    """Cancels the step once it has warned of a partial DEM: the warning comes before the work."""

    def isCanceled(self):
        return any("has heights under" in m for m in self.messages)


def test_a_dem_under_part_of_the_image_is_a_warning_with_its_share(scene, tmp_path):
    # issue 36: a DEM under a third of the image gave a third of an orthoimage, with no word
    middle = 0.5 * sum(scene["dsm"].height_range)
    ring = scene["hrg"].footprint(h=middle)
    dsm = scene["paths"]["dsm"]
    ds = gdal.Open(dsm)
    gt = ds.GetGeoTransform()
    cut = str(tmp_path / "west.tif")
    gdal.Translate(
        cut, dsm, projWin=[gt[0], gt[3], ring[:, 0].min() + np.ptp(ring[:, 0]) / 3.0, gt[3] + ds.RasterYSize * gt[5]]
    )
    log = StopAfterTheWarning()
    with pytest.raises(CancelledError):
        orthorectify_image(
            str(tmp_path / "west_ortho.tif"), cut, OrthoParams(cell_size=50.0), image=scene["image"], feedback=log
        )
    assert len(log.messages) == 1 and log.messages[0].startswith(f"the DEM {cut} has heights under ")
    share = float(log.messages[0].split("has heights under ")[1].split("%")[0]) / 100.0
    # the share warned of against the area of the footprint (at the DEM's middle height) inside the cut DEM, by
    # polygon geometry: equal to within the sampling (32 image points across)
    footprint = ogr.CreateGeometryFromWkt("POLYGON ((" + ", ".join(f"{x} {y}" for x, y in ring) + "))")
    x0, y1 = gdal.Open(cut).GetGeoTransform()[0], gdal.Open(cut).GetGeoTransform()[3]
    x1, y0 = gdal.Info(cut, format="json")["cornerCoordinates"]["lowerRight"]
    box = ogr.CreateGeometryFromWkt(f"POLYGON (({x0} {y0}, {x1} {y0}, {x1} {y1}, {x0} {y1}, {x0} {y0}))")
    inside = footprint.Intersection(box).GetArea() / footprint.GetArea()
    assert abs(share - inside) < 0.04 and 0.25 < share < 0.45
    assert dem_coverage(scene["hrg"], scene["dsm"]) == 1.0  # the whole DSM: no warning
    assert not (tmp_path / "west_ortho.tif").exists()
