"""Statistics of height differences dh (m): Kornus et al. 2006, Tables 3, 4, 6, 7 (N, min, mean, max, RMS, sigma;
adjustment.bundle.statistics_table, sigma with n - 1), the shares of Zhang and Gruen 2004, Tables 2-3 (|dh| < 2 m,
2 m <= |dh| <= 5 m, |dh| > 5 m, in %) and the robust extras NMAD = 1.4826 median(|dh - median(dh)|)
and the 95 % quantile of |dh| (linear interpolation between order statistics, numpy's default)."""
from dataclasses import dataclass

import numpy as np

from ..stats import NMAD_SCALE, statistics_table

SHARE_LIMITS = (2.0, 5.0)
QUANTILE = 0.95


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
    q95: float          # 95 % quantile of |dh|
    shares: tuple       # % of |dh| < 2, 2-5, > 5 m


def summarize(dh):
    """Stats of the finite values of `dh`."""
    dh = np.asarray(dh, float).ravel()
    dh = dh[np.isfinite(dh)]
    n, lo, mean, hi, rms, sigma = statistics_table({"dh": dh})["dh"]
    if not n:
        return Stats(0, lo, mean, hi, rms, sigma, float("nan"), float("nan"), float("nan"), (float("nan"),) * 3)
    median = float(np.median(dh))
    a = np.abs(dh)
    small, large = SHARE_LIMITS
    shares = tuple(100.0 * float(np.count_nonzero(m)) / n for m in (a < small, (a >= small) & (a <= large), a > large))
    return Stats(n, lo, mean, hi, rms, sigma, median, NMAD_SCALE * float(np.median(np.abs(dh - median))),
                 float(np.quantile(a, QUANTILE)), shares)


def by_label(dh, labels, names):
    """[(name, Stats)] per label value in `names` ({value: name}, in its order) that has values."""
    dh, labels = np.asarray(dh, float), np.asarray(labels)
    rows = []
    for value, name in names.items():
        mask = labels == value
        if mask.any():
            rows.append((name, summarize(dh[mask])))
    return rows


def cumulative(dh, labels, names):
    """Zhang and Gruen 2004, Tables 2-3: [(name, Stats)] of nested class sets, all classes first, then the class
    with the largest RMS left out, and so on down to the best class alone ("open+city+trees", ...)."""
    dh, labels = np.asarray(dh, float), np.asarray(labels)
    single = {value: summarize(dh[labels == value]) for value in names if np.any(labels == value)}
    order = sorted(single, key=lambda v: single[v].rms)
    rows = []
    for k in range(len(order), 0, -1):
        keep = order[:k]
        rows.append(("+".join(names[v] for v in keep), summarize(dh[np.isin(labels, keep)])))
    return rows
