"""Multi-image points (mass points and tie points).

A `MultiPoints` holds two numpy structured arrays:

- `points` (POINT_DTYPE), one row per ground point: id, group (1 two-ray, 2 three-ray from two
  combinations, 3 three-ray from all three combinations; paper K 3.3), `flags` (the combinations
  that matched it: COMB_A nadir-forward, COMB_B nadir-backward, COMB_C backward-forward; and
  REFINED where MPGC refined its search positions, refinement.py; the coarse-to-fine strategy's
  NCC_ONLY and EDGE: coarse_to_fine.py; DENSE: dense matching, dense/dense_strategy.py),
  rho_min (the smallest correlation coefficient of its combinations), rho_a/rho_b/rho_c (NaN
  where that combination did not match it) and dx/dy, the deviation of the doubly determined
  coordinates of group 3 points from their average (px of the forward image; NaN otherwise);
- `observations` (OBS_DTYPE), one row per image measurement: point id, block image id, col, row
  (GDAL convention), rho and the error-ellipse semi-axes (px) of the match that gave it (MPGC's
  for REFINED points, whose rho_min and rho_a/b/c stay the combinations' values). The
  first image of a combination is not matched (it is the template position): rho NaN, axes 0.
  Observations are sorted by point id, then image id.

`stats` is a small dict of run-level numbers (e.g. the count of group 3 points before the 3-sigma
test and the robust sigmas), kept with the points.

Storage beside the block: block/points.py.
"""

import numpy as np

# flag bits of POINT_DTYPE["flags"], one place for both matching strategies
COMB_A, COMB_B, COMB_C = 1, 2, 4
#: coarse-to-fine: a point MPGC did not accept (coarse_to_fine.py, step 4)
NCC_ONLY = 8
#: coarse-to-fine: a point matched as an edgel (coarse_to_fine.py, step 2)
EDGE = 16
#: region growing: a three-ray point whose search positions MPGC refined (refinement.py)
REFINED = 32
#: dense matching: a point of the semi-global matcher (dense/dense_strategy.py)
DENSE = 64
#: dense matching: a point whose positions the bias test kept at the semi-global matcher's (dense/refine.py)
SEMI_GLOBAL = 128

POINT_DTYPE = np.dtype(
    [
        ("id", "i8"),
        ("group", "i1"),
        ("flags", "u1"),
        ("rho_min", "f4"),
        ("rho_a", "f4"),
        ("rho_b", "f4"),
        ("rho_c", "f4"),
        ("dx", "f4"),
        ("dy", "f4"),
    ]
)
OBS_DTYPE = np.dtype(
    [
        ("point_id", "i8"),
        ("image_id", "i4"),
        ("col", "f8"),
        ("row", "f8"),
        ("rho", "f4"),
        ("semi_major", "f4"),
        ("semi_minor", "f4"),
    ]
)


class MultiPoints:
    """Points seen in several images: `points` (POINT_DTYPE) and `observations` (OBS_DTYPE)."""

    def __init__(self, points=None, observations=None, stats=None):
        self.points = np.zeros(0, POINT_DTYPE) if points is None else np.asarray(points, POINT_DTYPE)
        self.observations = np.zeros(0, OBS_DTYPE) if observations is None else np.asarray(observations, OBS_DTYPE)
        self.stats = dict(stats or {})

    def __len__(self):
        return len(self.points)

    def __repr__(self):
        return f"MultiPoints({len(self.points)} points, {len(self.observations)} observations)"

    def image_ids(self):
        return np.unique(self.observations["image_id"])

    def observations_of(self, image_id):
        """(point ids, col, row) of the observations in image `image_id`, sorted by point id."""
        obs = self.observations[self.observations["image_id"] == image_id]
        return obs["point_id"], obs["col"], obs["row"]

    def coordinates(self, image_id):
        """col, row of every point in image `image_id`, in the order of `points` (NaN where the
        point has no observation there)."""
        col = np.full(len(self.points), np.nan)
        row = np.full(len(self.points), np.nan)
        ids, c, r = self.observations_of(image_id)
        pos = np.searchsorted(self.points["id"], ids)
        col[pos], row[pos] = c, r
        return col, row

    def subset(self, point_ids):
        """The points with the given ids and their observations (same stats)."""
        point_ids = np.asarray(point_ids, np.int64)
        keep = np.isin(self.points["id"], point_ids)
        obs_keep = np.isin(self.observations["point_id"], point_ids)
        return MultiPoints(self.points[keep], self.observations[obs_keep], self.stats)

    def group_counts(self):
        """{group: count} for groups 1, 2, 3."""
        return {g: int(np.count_nonzero(self.points["group"] == g)) for g in (1, 2, 3)}
