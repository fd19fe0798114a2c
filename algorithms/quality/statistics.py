"""Statistics of height differences dh (m): Kornus et al. 2006, Tables 3, 4, 6, 7 (N, min, mean, max, RMS, sigma;
sigma with n - 1), the shares of Zhang and Gruen 2004, Tables 2-3 (|dh| < 2 m, 2 m <= |dh| <= 5 m, |dh| > 5 m,
in %) and the robust extras NMAD = 1.4826 median(|dh - median(dh)|) and the 95 % quantile of |dh| (linear
interpolation between order statistics, numpy's default).

The statistics come from a DhSummary, which the parts of an assessment (chunks of points, tiles of a DEM) add
up: exact counts, sums (N, mean, RMS, sigma, min, max, shares) and a sparse histogram of dh in STEP bins
(histogram.py) for the median, NMAD and quantile, which are therefore those of dh rounded to STEP (within
STEP / 2 of the exact ones for the median and quantile, within STEP for NMAD)."""

import math
from dataclasses import dataclass, field

import numpy as np

from .. import histogram
from ..stats import NMAD_SCALE

SHARE_LIMITS = (2.0, 5.0)
QUANTILE = 0.95
#: dh bin of the summaries' histograms (m)
STEP = 1e-3


@dataclass(frozen=True)
class Stats:
    n: int
    min: float
    mean: float
    max: float
    rms: float
    sigma: float
    median: float
    nmad: float
    q95: float  # 95 % quantile of |dh|
    shares: tuple  # % of |dh| < 2, 2-5, > 5 m


@dataclass
class DhSummary:
    """What the statistics of a set of dh need, mergeable: count, sum, sum of squares, extremes, share counts
    and the histogram of dh in STEP bins."""

    n: int = 0
    total: float = 0.0
    squares: float = 0.0
    low: float = math.inf
    high: float = -math.inf
    share_counts: tuple = (0, 0, 0)
    hist: tuple = field(default_factory=lambda: histogram.EMPTY)

    @classmethod
    def of(cls, dh):
        """The summary of the finite values of `dh`."""
        dh = np.asarray(dh, float).ravel()
        dh = dh[np.isfinite(dh)]
        if not dh.size:
            return cls()
        a = np.abs(dh)
        small, large = SHARE_LIMITS
        shares = tuple(int(np.count_nonzero(m)) for m in (a < small, (a >= small) & (a <= large), a > large))
        return cls(
            int(dh.size),
            float(dh.sum()),
            float(np.dot(dh, dh)),
            float(dh.min()),
            float(dh.max()),
            shares,
            histogram.count(np.round(dh / STEP)),
        )

    def merge(self, other):
        """The summary of both sets."""
        return DhSummary(
            self.n + other.n,
            self.total + other.total,
            self.squares + other.squares,
            min(self.low, other.low),
            max(self.high, other.high),
            tuple(a + b for a, b in zip(self.share_counts, other.share_counts)),
            histogram.add(self.hist, other.hist),
        )

    def values(self):
        """(dh of each bin, count)."""
        return self.hist[0] * STEP, self.hist[1]

    def stats(self):
        """The Stats of the set."""
        nan = float("nan")
        if not self.n:
            return Stats(0, nan, nan, nan, nan, nan, nan, nan, nan, (nan,) * 3)
        n, mean = self.n, self.total / self.n
        sigma = math.sqrt(max(self.squares - n * mean * mean, 0.0) / (n - 1)) if n > 1 else nan
        values, counts = self.values()
        median = histogram.median(values, counts)
        return Stats(
            n,
            self.low,
            mean,
            self.high,
            math.sqrt(self.squares / n),
            sigma,
            median,
            NMAD_SCALE * histogram.median(np.abs(values - median), counts),
            histogram.quantile(np.abs(values), counts, QUANTILE),
            tuple(100.0 * c / n for c in self.share_counts),
        )


def summarize(dh):
    """Stats of the finite values of `dh`."""
    return DhSummary.of(dh).stats()


def labelled(dh, labels):
    """{label value: DhSummary} of the dh of each value of `labels`."""
    dh, labels = np.asarray(dh, float), np.asarray(labels)
    return {int(v): DhSummary.of(dh[labels == v]) for v in np.unique(labels)}


def merge_labelled(a, b):
    """The sum of two labelled summaries."""
    out = dict(a)
    for value, summary in b.items():
        out[value] = out[value].merge(summary) if value in out else summary
    return out


def by_label(summaries, names):
    """[(name, Stats)] per label value in `names` ({value: name}, in its order) that has values, from the
    labelled summaries {value: DhSummary}."""
    return [
        (name, summaries[value].stats()) for value, name in names.items() if value in summaries and summaries[value].n
    ]


def cumulative(summaries, names):
    """Zhang and Gruen 2004, Tables 2-3: [(name, Stats)] of nested class sets, all classes first, then the class
    with the largest RMS left out, and so on down to the best class alone ("open+city+trees", ...)."""
    single = {value: summaries[value] for value in names if value in summaries and summaries[value].n}
    order = sorted(single, key=lambda v: single[v].stats().rms)
    rows = []
    for k in range(len(order), 0, -1):
        merged = single[order[0]]
        for value in order[1:k]:
            merged = merged.merge(single[value])
        rows.append(("+".join(names[v] for v in order[:k]), merged.stats()))
    return rows
