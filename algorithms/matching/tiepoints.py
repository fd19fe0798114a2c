"""Tie point selection (Kornus et al. 2006, section 3.3): one point per regular grid cell of the reference image
(default 100 x 100 px), the one with the highest rho among the most reliable group present in
that cell (group 3 before 2 before 1; rho = the point's smallest correlation coefficient)."""

import math

import numpy as np

from ..errors import InputError
from .points import MultiPoints


def select_tie_points(points, cell=100.0, reference_image_id=None, min_group=1):
    """The MultiPoints subset of the selected tie points (ids kept).

    `reference_image_id` is the block id of the image whose grid is used (default: the first
    image of the points' stats, else the smallest image id observed); points without an
    observation there, or of a group below `min_group`, are not candidates."""
    if not 0 < cell < math.inf:
        raise InputError(f"the tie point cell size must be a positive number of pixels, got {cell}")
    if reference_image_id is None:
        images = points.stats.get("images") or points.image_ids().tolist()
        if not len(images):
            return MultiPoints(stats=points.stats)
        reference_image_id = int(images[0])
    ids, col, row = points.observations_of(reference_image_id)
    pos = np.searchsorted(points.points["id"], ids)
    group = points.points["group"][pos].astype(np.int64)
    rho = points.points["rho_min"][pos].astype(np.float64)
    ok = (group >= min_group) & np.isfinite(col) & np.isfinite(row)
    ids, col, row, group, rho = ids[ok], col[ok], row[ok], group[ok], np.nan_to_num(rho[ok], nan=-2.0)
    if len(ids) == 0:
        return MultiPoints(stats=points.stats)
    cx = np.floor(col / cell).astype(np.int64)
    cy = np.floor(row / cell).astype(np.int64)
    key = (cy << 32) + cx
    # sort by cell, then group descending, then rho descending, then id (deterministic)
    order = np.lexsort((ids, -rho, -group, key))
    first = np.ones(len(order), bool)
    first[1:] = key[order][1:] != key[order][:-1]
    selected = points.subset(ids[order][first])
    selected.stats = dict(points.stats, tie_cell=float(cell), tie_reference=int(reference_image_id))
    return selected
