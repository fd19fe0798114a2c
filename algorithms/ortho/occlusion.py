"""Occlusion: a cell is occluded when its line of sight to the sensor passes below the DEM surface.

Per tile the line of sight is taken as straight with a constant direction (dlon/dh, dlat/dh): the shift
of the ground point of one image point per metre of height, from model.image_to_ground at two heights
at the tile's centre (the view direction changes by a fraction of a degree over a tile). From a cell's
ground point (lon, lat, h) the ray is marched upwards in height steps of a quarter DEM cell horizontally;
the cell is occluded if the DEM at the ray's ground position rises above the ray by more than TOLERANCE
before the ray passes the DEM's highest height. Positions outside the DEM do not block. This is the
definition itself (no image-space z-buffer, hence no false occlusions of foreshortened slopes that fall
into one image pixel); its cost per cell is (h_max - h) / step DEM look-ups."""

import math

import numpy as np
from numba import njit

from ..dem import bilinear_scalar

#: m: the DEM must rise above the ray by more than this to block it
TOLERANCE = 0.01


@njit(cache=True, nogil=True)
def occlusion_kernel(heights, gt, lon, lat, h, dlon_dh, dlat_dh, h_step, h_top, tol, occluded):
    """occluded[p] = whether the ray from (lon[p], lat[p], h[p]) along (dlon_dh, dlat_dh) per metre of
    height meets the DEM (grid `heights`, geotransform `gt`) before it climbs above h_top."""
    for p in range(lon.size):
        occluded[p] = False
        if not math.isfinite(h[p]):
            continue
        k = 1
        while True:
            dh = k * h_step
            ray = h[p] + dh
            if ray > h_top:
                break
            z = bilinear_scalar(heights, gt[0], gt[1], gt[3], gt[5], lon[p] + dh * dlon_dh, lat[p] + dh * dlat_dh)
            if z > ray + tol:
                occluded[p] = True
                break
            k += 1


def ray_direction(model, col, row, h_low, h_high):
    """(dlon/dh, dlat/dh) of the line of sight of image point (col, row) (clipped to the image) between
    heights h_low and h_high; None where the model gives no ground point."""
    cols, rows = model.size
    c, r = min(max(col, 0.0), cols), min(max(row, 0.0), rows)
    lon, lat = model.image_to_ground_or_nan(np.array([c, c]), np.array([r, r]), np.array([h_low, h_high]))
    if not np.all(np.isfinite(lon)) or not np.all(np.isfinite(lat)):
        return None
    return (lon[1] - lon[0]) / (h_high - h_low), (lat[1] - lat[0]) / (h_high - h_low)


def occluded(dem, lon, lat, h, direction):
    """Boolean occlusion mask (shape of lon) of ground points whose rays have direction (dlon/dh, dlat/dh)."""
    dlon_dh, dlat_dh = direction
    gt = np.asarray(dem.geotransform, np.float64)
    cells_per_m = math.hypot(dlon_dh / gt[1], dlat_dh / gt[5])
    h_low, h_top = dem.height_range
    h_step = 0.25 / cells_per_m if cells_per_m > 0 else h_top - h_low + 1.0
    out = np.zeros(lon.size, np.bool_)
    occlusion_kernel(
        dem.heights,
        gt,
        *(np.ascontiguousarray(a, np.float64).ravel() for a in (lon, lat, h)),
        float(dlon_dh),
        float(dlat_dh),
        float(h_step),
        float(h_top),
        TOLERANCE,
        out,
    )
    return out.reshape(np.shape(lon))
