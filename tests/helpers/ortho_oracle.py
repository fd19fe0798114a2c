"""Geometric error of an orthoimage against the simulator's true orthoimage (same grid), by least-squares
matching: shared by the orthorectification and the end-to-end tests."""

import numpy as np
from osgeo import gdal
from scipy import ndimage

from pushbroom.algorithms.matching import lsm
from pushbroom.algorithms.matching.params import LsmParams
from pushbroom.algorithms.simulation.terrain import BARE, CROPS


def geometric_error(paths, ortho_path, classes=(BARE, CROPS)):
    """(n, 2) LSM shifts (output cells) of the orthoimage against the true orthoimage at a 15-cell
    lattice of `classes` cells whose whole template has values (DEM gaps are nodata), accepted
    patches only."""
    truth = gdal.Open(str(paths["orthoimage"])).ReadAsArray().astype(np.float32)
    ours = gdal.Open(str(ortho_path)).ReadAsArray().astype(np.float32)
    land = gdal.Open(str(paths["classes"])).ReadAsArray()
    full = ndimage.binary_erosion(ours > 0, np.ones((LsmParams.template + 4,) * 2))
    i, j = (a.ravel() for a in np.mgrid[20 : truth.shape[0] - 20 : 15, 20 : truth.shape[1] - 20 : 15])
    keep = full[i, j] & np.isin(land[i, j], classes)
    x, y = j[keep] + 0.5, i[keep] + 0.5
    records, status = lsm.match_points(truth, ours, x, y, x, y)
    ok = lsm.accepted(records, status)
    return np.column_stack([records["x2"][ok] - x[ok], records["y2"][ok] - y[ok]])
