"""A folder holding every kind of input the Processing steps read, copied from the small scene so that a test
may try to overwrite it: a block (its control points, mass and tie point folders, and the images it refers to),
a DSM and a DTM, a point cloud; each raster as QGIS leaves it once loaded (with the .aux.xml of statistics it
writes), so that what the tests' runs find does not change as they load them. Used by the output-path tests
(tests/plugin/test_output_paths_*.py)."""

import csv
import os
import pathlib
import shutil

import numpy as np
from qgis.core import QgsRasterLayer

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.surface.pointcloud import write_point_cloud
from tests.helpers.adjustment_scene import NAMES
from tests.helpers.points_synthetic import synthetic


def build(folder, scene):
    """The inputs in `folder`: {'folder', 'block', 'images' (IMAGERY.TIF paths), 'dsm', 'dtm', 'las'}."""
    folder = pathlib.Path(folder)
    for name in NAMES:
        shutil.copytree(os.path.dirname(scene["images"][name]["imagery"]), folder / name)
    for name in ("dsm", "dtm"):
        shutil.copy(scene[name], folder / f"{name}.tif")
    block = folder / "block.gpkg"
    images = [str(folder / name / "IMAGERY.TIF") for name in NAMES]
    Block.create(block, Block.open_images(images), height=300.0)
    cp.import_csv(Block(block), scene["points"], suffix="_meas")
    ids = list(Block(block).image_ids().values())
    Block(block).store_points(synthetic(60, images=ids))
    Block(block).store_points(synthetic(20, seed=1, images=ids), "tie_points")
    with open(scene["points"], newline="") as f:
        rows = list(csv.DictReader(f))
    lon, lat, h = (np.array([float(r[k]) for r in rows]) for k in ("lon", "lat", "h"))
    write_point_cloud(folder / "cloud.las", lon, lat, h)
    for raster in [*images, folder / "dsm.tif", folder / "dtm.tif"]:
        QgsRasterLayer(str(raster), "", "gdal")  # writes the GDAL side file of statistics QGIS keeps of a raster
    return {
        "folder": str(folder),
        "block": str(block),
        "images": images,
        "dsm": str(folder / "dsm.tif"),
        "dtm": str(folder / "dtm.tif"),
        "las": str(folder / "cloud.las"),
    }
