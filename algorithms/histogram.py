"""Sparse histograms: the mergeable form of a distribution, so that the parts of a tiled run add up to
the statistics of the whole.

A histogram is a pair (bins, counts) of int64 arrays, bins ascending and unique: the values of a bin
are those a caller's key function maps to it (a quantisation step, a log scale). Adding two
histograms is exact and independent of the order, so a statistic taken from the merged histogram of
the tiles equals the one taken from the histogram of all values at once, whatever the tiling.
Medians and quantiles are of the bins' representative values (the caller's), so they are exact to
within a bin."""

import numpy as np

EMPTY = (np.zeros(0, np.int64), np.zeros(0, np.int64))


def count(keys):
    """The histogram of the integer bin `keys` of a set of values."""
    bins, counts = np.unique(np.asarray(keys, np.int64), return_counts=True)
    return bins, counts.astype(np.int64)


def add(a, b):
    """The sum of the histograms a and b."""
    bins, inverse = np.unique(np.concatenate([a[0], b[0]]), return_inverse=True)
    return bins, np.bincount(inverse, weights=np.concatenate([a[1], b[1]]), minlength=len(bins)).astype(np.int64)


def total(hists):
    """The sum of an iterable of histograms."""
    out = EMPTY
    for h in hists:
        out = add(out, h)
    return out


def _ranked(values, counts, ranks):
    """The values at the 1-based `ranks` of values[i] repeated counts[i] times (values in any order)."""
    order = np.argsort(values, kind="stable")
    cumulative = np.cumsum(counts[order])
    return [values[order[int(np.searchsorted(cumulative, rank))]] for rank in ranks]


def median(values, counts):
    """The median of values[i] repeated counts[i] times (values in any order), as numpy's median: the
    mean of the two middle order statistics, the middle one for an odd count; NaN when empty."""
    values, counts = np.asarray(values, float), np.asarray(counts, np.int64)
    n = int(counts.sum())
    if n == 0:
        return float("nan")
    lower, upper = _ranked(values, counts, ((n + 1) // 2, n // 2 + 1))
    return float((lower + upper) / 2)


def quantile(values, counts, q):
    """The q quantile (0..1) of values[i] repeated counts[i] times, by linear interpolation between order
    statistics (numpy's default); NaN when empty."""
    values, counts = np.asarray(values, float), np.asarray(counts, np.int64)
    n = int(counts.sum())
    if n == 0:
        return float("nan")
    position = q * (n - 1)
    below, above = int(np.floor(position)), int(np.ceil(position))
    lo, hi = _ranked(values, counts, (below + 1, above + 1))
    return float(lo + (hi - lo) * (position - below))
