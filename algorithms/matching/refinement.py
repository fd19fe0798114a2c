"""MPGC refinement of region growing's three-ray points (group 3): the final step of Zhang and Gruen
(2004) applied to the combinations of Kornus et al. (2006).

Group 3 points have a template position in the reference image and matched positions in both
search images: the forward one the average of combinations (a) and (c), the backward one from (b).
Each match saw one search image at a time. MPGC (mpgc.py) matches the template into both search
images at once, tied by the sensor models to one object point, with Tukey weights against samples
that see another surface (canopy or a roof inside a field's template). The reference position is
kept, so transfer points keep their first-image coordinates.

Orientation: the search images' models are corrected by affine image biases fitted to the points'
rays (orientation_bias.py) and the geometric observations weighted by sigma_geometry =
max(SIGMA_GEOMETRY, 2 x the corrected orientation's inconsistency), or MPGC's default
(MpgcParams, 0.2 px) where no tile holds enough points to measure it. Fewer than MIN_POINTS
group 3 points (6 bias parameters per search image) are left as they are. A tiled run
(tiled_rounds.py) fits the biases once to a sample of the scene's points and refines each tile with
them. Template, thresholds
and iterations are region growing's (GrowParams), and so is the resolution adaptation.

A point whose MPGC result passes mpgc.accepted takes MPGC's search positions, correlation and
error ellipses and the flag REFINED; the others keep region growing's positions.

With GrowParams.support_weights (off by default; on in the DEM pipeline model) MPGC's support
weights (SUPPORT_CENTRE, SUPPORT_SIMILARITY) make each match measure the surface around its
template centre rather than average in the forest, city or water beside a field.
Figures: docs/validation.md#group3-accuracy, docs/validation.md#mpgc-support-weights."""

from dataclasses import fields
from typing import Any

import numpy as np

from .. import progress
from ..progress import Feedback
from .mpgc import MpgcParams, accepted, match_points
from .orientation_bias import affine_bias, intersect_corrected
from .params import GrowParams, LsmParams
from .points import REFINED, MultiPoints
from .resolution import adapted_images
from .stereo_set import StereoSet

#: px: sigma of the geometric observations where the corrected orientation is consistent
#: (docs/validation.md#group3-accuracy)
SIGMA_GEOMETRY = 0.05
#: fewest group 3 points the refinement runs on
MIN_POINTS = 50
#: MPGC's support weights (module docstring): px of the Gaussian centre weight, and the grey-level
#: scale in units of the template's standard deviation
SUPPORT_CENTRE, SUPPORT_SIMILARITY = 5.0, 1.0


def refine_three_ray(
    points: MultiPoints,
    stereo: StereoSet,
    grow: GrowParams | None = None,
    feedback: Feedback | None = None,
    bias: tuple[Any, float] | None = None,
    group: int = 3,
    exclude: np.ndarray | None = None,
) -> int:
    """MPGC refinement of the `group` points (three rays: region growing's 3, dense matching's 2) of `points`
    (MultiPoints of three_combinations.combine or dense/dense_strategy.py; `stereo` the StereoSet: images and
    models in combination order, their block ids, the height range; `grow` the GrowParams of the matching).
    `bias`: (corrected models, systematic px) of orientation_bias.affine_bias fitted to the points of the whole
    scene (tiled_rounds.scene_bias: the points of one tile are refined with it), else fitted here to `points`.
    `exclude`: a mask of the points not to refine (None: none). Returns the number of points refined; `points` is
    changed in place (module docstring)."""
    images, models, image_ids = list(stereo.images), list(stereo.models), list(stereo.ids)
    grow = grow or GrowParams()
    g3 = np.flatnonzero((points.points["group"] == group) & (True if exclude is None else ~np.asarray(exclude)))
    if g3.size < (MIN_POINTS if bias is None else 1):
        return 0
    cols, rows = (np.array(v) for v in zip(*(points.coordinates(i) for i in image_ids)))
    cols, rows = cols[:, g3], rows[:, g3]
    progress.step(feedback, 0, f"MPGC refinement of {g3.size} three-ray points")
    if bias is None:
        corrected, inter, systematic = affine_bias(models, cols, rows)
    else:
        corrected, systematic = bias
        inter = intersect_corrected(models, corrected, cols, rows)
    lsm = {f.name: getattr(grow, f.name) for f in fields(LsmParams)}
    support = {"centre_sigma": SUPPORT_CENTRE, "similarity": SUPPORT_SIMILARITY} if grow.support_weights else {}
    params = MpgcParams(
        **lsm,
        **support,
        **({"sigma_geometry": max(SIGMA_GEOMETRY, 2.0 * systematic)} if np.isfinite(systematic) else {}),
    ).check()
    ok = np.isfinite(inter.h)
    adapted = adapted_images(images, models, stereo.heights.bounds, grow)
    rec = match_points(
        adapted[0],
        adapted[1:],
        corrected,
        cols[0, ok],
        rows[0, ok],
        (inter.lon[ok], inter.lat[ok], inter.h[ok]),
        params,
        progress.scaled(feedback, 5, 100),
    )
    good = accepted(rec, params)
    which = g3[ok][good]
    obs = points.observations
    first = np.searchsorted(obs["point_id"], points.points["id"][which])  # a point's 3 rows, by image id
    rows3 = first[:, None] + np.arange(3)
    for c, image_id in enumerate(image_ids[1:]):
        pos = rows3[np.arange(which.size), np.argmax(obs["image_id"][rows3] == image_id, axis=1)]
        obs["col"][pos], obs["row"][pos] = rec["x"][good, c], rec["y"][good, c]
        obs["rho"][pos] = rec["rho"][good, c]
        obs["semi_major"][pos], obs["semi_minor"][pos] = rec["semi_major"][good, c], rec["semi_minor"][good, c]
    points.points["flags"][which] |= REFINED
    bias = [np.r_[m.dx, m.dy, m.linear.ravel() - np.eye(2).ravel()].round(4).tolist() for m in corrected[1:]]
    points.stats.update(
        {
            "refined_mpgc": int(which.size),
            "refine_sigma_geometry_px": round(params.sigma_geometry, 4),
            "refine_bias_px": bias,
        }
    )
    return int(which.size)
