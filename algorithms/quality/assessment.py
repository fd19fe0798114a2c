"""The accuracy assessment as one call: dh of a point cloud and/or a DEM against a reference
(height_differences), each value labelled with its class (a class raster or polygons, classes.py)
and its slope class (flat/moderate vs mountainous, Kornus et al. 2006, section 3.7), ready for the tables and
figures of report.py."""
from dataclasses import dataclass

import numpy as np

from .. import progress
from ..errors import InputError
from .classes import slope_classes
from .height_differences import Differences, dem_differences, point_differences

SLOPE_THRESHOLD = 10.0   # degrees


@dataclass
class Assessed:
    differences: Differences
    classes: np.ndarray = None      # (n,) class of each dh (classes.NO_CLASS: none)
    class_names: dict = None
    terrain: np.ndarray = None      # (n,) classes.FLAT / MOUNTAINOUS
    terrain_names: dict = None


def labels(source, differences):
    """Class of each dh of `differences` from a ClassRaster or PolygonClasses."""
    if differences.grid is not None:
        return source.on_grid(differences.grid)[differences.valid]
    return source.at_points(differences.x, differences.y, differences.srs)


def assess(reference, points=None, dem=None, reference_datum="ellipsoidal", points_datum="ellipsoidal",
           dem_datum="ellipsoidal", classes=None, slope_threshold=SLOPE_THRESHOLD, feedback=None,
           reference_nodata=None):
    """[Assessed] of the point cloud `points` and the DEM raster `dem` (either or both) against the
    `reference` raster; `classes` a classes.ClassRaster or classes.PolygonClasses (or None);
    `reference_nodata` a void value of the reference that its file does not flag as nodata. Implausible
    reference heights are reported as a warning (height_differences)."""
    if points is None and dem is None:
        raise InputError("give a point cloud, a DEM or both to assess")
    if not slope_threshold > 0:
        raise InputError(f"the slope threshold must be a positive angle in degrees, not {slope_threshold}")
    jobs = [(point_differences, points, points_datum), (dem_differences, dem, dem_datum)]
    jobs = [job for job in jobs if job[1] is not None]
    out = []
    for k, (compute, path, datum) in enumerate(jobs):
        span = 100.0 / len(jobs)
        d = compute(path, reference, reference_datum, datum, progress.scaled(feedback, k * span, (k + 0.8) * span),
                    reference_nodata=reference_nodata)
        if not d.dh.size:
            raise InputError(f"no {d.what} of {path} has a reference height: check that the reference covers it")
        terrain, terrain_names = slope_classes(d.slope, slope_threshold)
        assessed = Assessed(d, terrain=terrain, terrain_names=terrain_names)
        if classes is not None:
            assessed.classes, assessed.class_names = labels(classes, d), classes.names
        out.append(assessed)
        progress.step(feedback, (k + 1) * span, f"{d.what}: {d.dh.size} height differences")
    return out
