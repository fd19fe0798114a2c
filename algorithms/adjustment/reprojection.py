"""Image reprojection statistics of a bundle adjustment per image: how well the adjusted object
points, reprojected with the (adjusted) models, fit their image measurements. With nothing free,
`bundle.adjust(models, obs, free=[])` intersects every point from all its rays at the supplied
orientation, so the same statistics give the "before adjustment" figures.

For the measurements of the points of the given roles in image i, with v = computed - measured
(Adjustment.residuals, px):

    mean_col = mean(v_col), mean_row = mean(v_row)      (a systematic shift shows here)
    rms_col = sqrt(mean(v_col^2)), rms_row = sqrt(mean(v_row^2))
    rms = sqrt(mean(v_col^2 + v_row^2))                 (RMS length of the residual vectors)

and the same over all images (image_id ALL)."""

import numpy as np

from ..errors import InputError
from .observations import ROLES

#: image_id of the row over all images
ALL = -1
RMS_DTYPE = np.dtype(
    [
        ("image_id", "i8"),
        ("n", "i8"),
        ("mean_col", "f8"),
        ("mean_row", "f8"),
        ("rms_col", "f8"),
        ("rms_row", "f8"),
        ("rms", "f8"),
    ]
)


def _row(image_id, v):
    if not len(v):
        return (image_id, 0) + (np.nan,) * 5
    ms = np.mean(v * v, axis=0)
    return (image_id, len(v), *np.mean(v, axis=0), *np.sqrt(ms), np.sqrt(ms.sum()))


def reprojection_rms(result, roles=("tie",)):
    """RMS_DTYPE rows (module docstring): one per image id (ascending) with measurements of points of
    `roles` in Adjustment `result`, then the row over all of them (image_id ALL)."""
    unknown = set(roles) - set(ROLES)
    if unknown:
        raise InputError(f"unknown point role(s) {sorted(unknown)}; roles are {', '.join(ROLES)}")
    m = result.observations.measurements
    keep = np.isin(result.observations.points["role"][m["point"]], list(roles))
    v, ids = np.asarray(result.residuals, float)[keep], m["image_id"][keep]
    rows = [_row(int(i), v[ids == i]) for i in np.unique(ids)] + [_row(ALL, v)]
    return np.array(rows, RMS_DTYPE)
