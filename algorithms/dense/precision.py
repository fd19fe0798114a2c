"""The precision of the refined dense points: LSM's error ellipses and the surface around each point, calibrated
against the truth.

A dense point is refined when LSM refined every one of its matched positions (dense/refine.py; rho_min finite),
including the positions the bias test then sent back to their semi-global places (they stay measured).
Its height sigma has two parts:

1. Matching noise. Each refined position carries LSM's error ellipse relative to the template's position,
   semi-major axis a_i (px of image i; a position the wide window placed reports it in the template's units,
   lsm.match_accepted). The pair's relative error is shared between its two rays, and the
   reference image's position is the template that both pairs of a triplet share. The intersection
   (surface/intersection.py) propagates the image sigmas

       sigma_i = F_k a_i / sqrt(2)   (a matched image i),    sigma_0 = min_i sigma_i   (the reference image)

   (k the point's rays) into the point's sigma_h,rays. F_k calibrates the ellipse, which assumes white
   residuals where a dense template's are the relief and aliasing inside it (docs/validation.md#lsm-error-
   ellipse-threshold), and, for three rays, the two pairs' shared template.
2. The template's surface. A template that sees more than one height (a field beside a forest, a roof, a slope
   break) measures a mixture of them; that error grows with the heights' spread and no ellipse sees it. With
   s the local spread of the refined points' heights around the point (surface/local_spread.py, half-width R =
   SPREAD_RADIUS_PX reference pixels, the default template's half-width):

       sigma_h = sqrt(sigma_h,rays^2 + (C s)^2).

A position the bias test kept at its semi-global place (dense/refine.py: LSM's template straddles heights there)
carries a_i = SEMI_GLOBAL_AXIS instead of LSM's ellipse: the semi-global position's error in the same units.

F_k and C are the sensor's (`Calibration`; `calibration_of` picks them for a block's models): they absorb how the
images' noise, blur and resampling make LSM's ellipse optimistic or pessimistic, which a method cannot know.
- SPOT (the rigorous SPOT models): the points' F_2, F_3 and C fitted on the simulated 3 km SPOT 5 triplet against
  its truth (least squares of dh^2 on the open classes, `studies/dense_precision.py`: 1.80, 2.09, 0.46), times the
  DSM cells' factor 1.2: a cell's height, the median of its points, stands for the surface at its centre, an error
  its points' sigmas do not carry (studies/README.md#dense_cell_precision fits it on the cells of every class; the
  points are then about a fifth pessimistic on open ground). No real SPOT pixels have checked them.
- RPC (Pleiades and the other sub-metre sensors delivered with RPCs): F_2 and C fitted on the real Pleiades
  triplet's pair differences (`studies/pair_precision.py`); F_3 = F_2 times SPOT's F_3 / F_2, as pair differences
  hold no three-ray cell. Pair differences see only the error that differs between the pairs: the template's
  surface error that two pairs share through their reference image is invisible to them, so this C is a lower
  bound.
SEMI_GLOBAL_AXIS is fitted on the simulated kept positions' points of every class (studies/dense_precision). All
hold for LSM's default template (19 px) and the dense refinement's largest shift (DenseParams.max_shift; fitted
again when it changes).

Every other point (unrefined dense points, region growing's, coarse-to-fine's, tie points) keeps the one a
priori image sigma given, and no spread term."""

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..matching.points import DENSE
from ..sensors.base import SensorModel
from ..sensors.rpc import RpcModel
from .epipolar import pixel_gsd


class Calibration(NamedTuple):
    """A sensor's precision factors (module docstring): F_k by number of rays, and C of the spread term."""

    factors: dict[int, float]
    spread: float


#: the rigorous SPOT models' (module docstring; studies/README.md#dense_precision)
SPOT = Calibration({2: 2.15, 3: 2.5}, 0.55)
#: the RPC models' (module docstring; studies/README.md#pair_precision)
RPC = Calibration({2: 1.35, 3: 1.35 * 2.5 / 2.15}, 0.08)
#: px: both semi-axes of a semi-global position the bias test kept (dense/refine.py), in LSM's ellipse units: its
#: image sigma is F_k SEMI_GLOBAL_AXIS / sqrt(2) (module docstring)
SEMI_GLOBAL_AXIS = 0.3
#: px of the reference image: the spread's half-width R, the default template's (19 px) half-width
SPREAD_RADIUS_PX = 9.5


def calibration_of(models: Iterable[SensorModel]) -> Calibration:
    """The Calibration of a block's `models`: RPC where every one is an RPC model, else SPOT."""
    models = list(models)
    return RPC if models and all(isinstance(m, RpcModel) for m in models) else SPOT


def image_sigmas(
    points: np.ndarray, observations: np.ndarray, default: float, calibration: dict[int, float]
) -> np.ndarray:
    """Per observation (OBS_DTYPE rows sorted by point id, of the POINT_DTYPE `points`), the a priori sigma
    (px) for the intersection: the module docstring's for the refined dense points, `default` elsewhere.
    `calibration`: F_k by number of rays (Calibration.factors)."""
    sigma = np.full(len(observations), float(default))
    if len(observations) == 0 or len(points) == 0:
        return sigma
    slot = np.searchsorted(points["id"], observations["point_id"]).clip(max=len(points) - 1)
    refined = refined_dense(points)[slot]
    matched = np.isfinite(observations["rho"])
    if not refined.any():
        return sigma
    relative = np.where(matched, observations["semi_major"] / np.sqrt(2.0), np.inf)
    smallest = np.full(len(points), np.inf)
    np.minimum.at(smallest, slot, relative)
    rays = np.bincount(slot, minlength=len(points))
    factor = np.array([calibration.get(k, np.nan) for k in range(rays.max() + 1)])[rays[slot]]
    own = factor * np.where(matched, relative, smallest[slot])
    use = refined & np.isfinite(own) & (own > 0)
    sigma[use] = own[use]
    return sigma


def refined_dense(points: np.ndarray) -> np.ndarray:
    """Per POINT_DTYPE row, whether it is a refined dense point (module docstring)."""
    return ((points["flags"] & DENSE) != 0) & np.isfinite(points["rho_min"])


def spread_radius(model: SensorModel, col: float, row: float, h: float) -> float:
    """R (m): SPREAD_RADIUS_PX pixels of the reference image `model` at (col, row, h)."""
    return SPREAD_RADIUS_PX * pixel_gsd(model, float(col), float(row), float(h), (1.0, 0.0), (0.0, 1.0))[2]


def with_spread(sigma_h: ArrayLike, spread: ArrayLike, factor: float) -> np.ndarray:
    """sigma_h with the template's surface term of factor C = `factor` (Calibration.spread; module docstring);
    unchanged where the spread is NaN."""
    extra = np.where(np.isfinite(spread), factor * np.asarray(spread, float), 0.0)
    return np.sqrt(np.square(sigma_h) + extra * extra)
