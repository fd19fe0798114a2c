"""The terrain height range a step works in: the user's heights where given, else the block's.

A height range is a tuple (h_min, h_max) of ellipsoidal heights (m), a single height, or None (nothing
known). Matching searches along the rays between h_min and h_max; steps that need one starting height
(intersection, tie point display, RPC fitting checks) take its middle."""
import math

from .errors import InputError


def height_range(h_min, h_max, block_range):
    """(h_min, h_max) when both are given; one given: that height (the matcher searches it +- 500 m);
    neither: `block_range`, the range recorded in the block at its creation (DEM heights under the
    footprints, or the mean height +- 500 m). InputError where a given height is not a number or the lowest
    is above the highest."""
    for name, value in (("lowest", h_min), ("highest", h_max)):
        if value is not None and not math.isfinite(value):
            raise InputError(f"the {name} terrain height must be a number of metres, got {value}")
    if h_min is not None and h_max is not None:
        if h_min > h_max:
            raise InputError(f"the lowest terrain height ({h_min:g} m) is above the highest ({h_max:g} m): give "
                             "the lowest height first (swapped?)")
        return (h_min, h_max)
    if h_min is not None or h_max is not None:
        return float(h_min if h_min is not None else h_max)
    return block_range


def mean_height(height_range):
    """The middle of a height range (0 where nothing is known)."""
    if height_range is None:
        return 0.0
    if isinstance(height_range, tuple):
        return 0.5 * (height_range[0] + height_range[1])
    return float(height_range)
