"""The terrain height range a step works in: the user's heights where given, else the block's; and the
heights terrain on Earth can have (PLAUSIBLE_HEIGHTS), which every height a user gives is checked against.

A height range as given is a tuple (h_min, h_max) of ellipsoidal heights (m), a single height, or None (nothing
known). Matching resolves it once, to a HeightRange, and searches along the rays between its low and high ends;
steps that need one starting height (intersection, tie point display, RPC fitting checks) take its middle."""

import math
from dataclasses import dataclass
from typing import Union

import numpy as np
from numpy.typing import ArrayLike

from .errors import InputError

#: heights (m) of terrain on Earth, ellipsoidal or orthometric, with a margin: the Dead Sea shore lies at
#: -430 m, Everest at 8849 m, and the geoid departs from the ellipsoid by -106 .. +85 m, so that both kinds of
#: height of any terrain lie within
PLAUSIBLE_HEIGHTS = (-500.0, 9000.0)


#: a height range as a user or a block gives it: (h_min, h_max), one height, or None
GivenHeights = Union[tuple[float, float], float, None]
#: m searched either side of a single height given as the range
SINGLE_HEIGHT_SPAN = 500.0


@dataclass(frozen=True)
class HeightRange:
    """The ellipsoidal heights (m) that matching searches along the rays, low <= high, both finite."""

    low: float
    high: float

    @classmethod
    def resolve(cls, given: Union["HeightRange", GivenHeights], model: object = None) -> "HeightRange":
        """The range of `given`: a HeightRange as it is; (h_min, h_max); one height h (h +- SINGLE_HEIGHT_SPAN);
        None: the reference sensor `model`'s own `height_range` (an RPC's validity domain). InputError where none
        is known, or the ends are not finite or swapped."""
        if isinstance(given, HeightRange):
            return given
        if given is None:
            given = getattr(model, "height_range", None)
            if given is None:
                raise InputError(
                    "the height range of the scene is unknown: give height_range=(h_min, h_max) "
                    "or a mean ellipsoidal height (then +-500 m are searched)"
                )
        if np.ndim(given) == 0:
            h = float(given)
            given = (h - SINGLE_HEIGHT_SPAN, h + SINGLE_HEIGHT_SPAN)
        lo, hi = (float(v) for v in given)
        if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo:
            raise InputError(f"height_range must be (h_min, h_max) with h_min <= h_max, got {given}")
        return cls(lo, hi)

    @property
    def bounds(self) -> tuple[float, float]:
        """(low, high)."""
        return (self.low, self.high)

    @property
    def mean(self) -> float:
        """The middle of the range."""
        return 0.5 * (self.low + self.high)

    def __str__(self) -> str:
        return f"{self.low:g} to {self.high:g} m"


def outside_plausible(heights: ArrayLike) -> np.ndarray:
    """Bool array: where the finite `heights` lie outside PLAUSIBLE_HEIGHTS (NaN: False)."""
    heights = np.asarray(heights, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return (heights < PLAUSIBLE_HEIGHTS[0]) | (heights > PLAUSIBLE_HEIGHTS[1])


def check_height(value: float | None, what: str) -> float | None:
    """`value` (m) as a float; InputError naming `what` ("the mean height HEIGHT") where it is not finite or
    lies outside PLAUSIBLE_HEIGHTS. None passes as None (not given)."""
    if value is None:
        return None
    value = float(value)
    low, high = PLAUSIBLE_HEIGHTS
    if not math.isfinite(value):
        raise InputError(f"{what} must be a number of metres within {low:g} .. {high:g} m, not {value}")
    if outside_plausible(value):
        raise InputError(
            f"{what} of {value:g} m lies outside the heights of terrain on Earth ({low:g} .. {high:g} m, "
            "ellipsoidal or above sea level): give the terrain's height in metres (not feet, not "
            "a flying height)"
        )
    return value


def check_heights(
    h_min: float | None, h_max: float | None, lowest: str, highest: str
) -> tuple[float | None, float | None]:
    """(h_min, h_max), each checked by check_height (None: not given); InputError also where both are given and
    the lowest is above the highest. `lowest`, `highest` name them ("the lowest terrain height"); their
    parameters are MIN_HEIGHT and MAX_HEIGHT."""
    h_min = check_height(h_min, f"{lowest} (MIN_HEIGHT)")
    h_max = check_height(h_max, f"{highest} (MAX_HEIGHT)")
    if h_min is not None and h_max is not None and h_min > h_max:
        raise InputError(
            f"{lowest} ({h_min:g} m) is above the highest ({h_max:g} m): give the lowest height first (swapped?)"
        )
    return h_min, h_max


def height_range(h_min: float | None, h_max: float | None, block_range: tuple[float, float] | None) -> GivenHeights:
    """(h_min, h_max) when both are given; one given: that height (the matcher searches it +- 500 m);
    neither: `block_range`, the range recorded in the block at its creation (DEM heights under the
    footprints, or the mean height +- 500 m). InputError where a given height is not a number, lies outside
    PLAUSIBLE_HEIGHTS, or the lowest is above the highest (check_heights)."""
    h_min, h_max = check_heights(h_min, h_max, "the lowest terrain height", "the highest terrain height")
    if h_min is not None and h_max is not None:
        return (h_min, h_max)
    if h_min is not None:
        return h_min
    if h_max is not None:
        return h_max
    return block_range


def mean_height(height_range: GivenHeights) -> float:
    """The middle of a height range as given (0 where nothing is known)."""
    if height_range is None:
        return 0.0
    if isinstance(height_range, tuple):
        return 0.5 * (height_range[0] + height_range[1])
    return float(height_range)
