"""Shared fixture data for the region-growing and seed tests: a small simulated SPOT 5 triplet and
the true image-2 position of image-1 points (image-1 truth ray meets the true DSM, projected by the
image-2 truth model)."""
import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.simulation.terrain import BARE, WATER

LOW_TEXTURE = (BARE, WATER)


class Scene:
    def __init__(self, folder, first="HRG", second="HRS1"):
        self.paths = paths = simulate_scene(SceneConfig.small(configuration="spot5_triplet"), folder)
        self.image1 = paths["images"][first]["imagery"]
        self.image2 = paths["images"][second]["imagery"]
        self.model1 = sensors.load(paths["images"][first]["metadata"])
        self.model2 = sensors.load(paths["images"][second]["metadata"])
        self.truth1 = sensors.load(paths["truth_metadata"][first])
        self.truth2 = sensors.load(paths["truth_metadata"][second])
        self.dsm = Dem.from_file(paths["dsm"])
        lo, hi = self.dsm.height_range
        self.height_range = (lo - 100.0, hi + 100.0)
        ds = gdal.Open(str(paths["classes"]))
        self.classes = ds.ReadAsArray()
        self.class_gt = ds.GetGeoTransform()

    def truth(self, x1, y1):
        """(x2, y2, class) of image-1 points."""
        lon, lat, h = self.truth1.image_to_dem(np.asarray(x1, float), np.asarray(y1, float), self.dsm)
        x2, y2 = self.truth2.ground_to_image(lon, lat, h)
        gt = self.class_gt
        i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, self.classes.shape[0] - 1)
        j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, self.classes.shape[1] - 1)
        return np.asarray(x2), np.asarray(y2), self.classes[i, j]
