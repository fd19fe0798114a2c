"""A per-cell DSM of a dense point cloud: each cell's height is a robust fusion of the points that fall in it.

For the points of one cell (x0 + c cell <= x < x0 + (c + 1) cell, likewise in y), with median m and
MAD = median |z - m|:
- outliers: points with |z - m| > k max(1.4826 MAD, MIN_SPREAD) are dropped (k = 0: none; a statistical
  filter within the cell: a mismatch lands metres off the surface its neighbours agree on);
- height: the median of the points kept;
- count: the points kept;
- precision (m): the standard error of a median, 1.2533 s / sqrt(n), with s the RMS of the kept points'
  sigma_h where every one has it, else 1.4826 MAD of the kept points (n >= 3; NaN below).
A cell without a point is NaN (a gap), never filled here. Points on the grid's far edges belong to its last
column and row.

Tiers: where the points carry a `tier` (0 the most precise: dense points LSM refined, or any sparse point; 1
those it left at the semi-global position), a cell uses only the points of the best tier it has; with
`fallback` off, no point of a tier above 0 is used (such a cell is a gap). studies/dense_fusion.py measures
why: the unrefined points' heights are worse than the refined ones' everywhere but in the city, and worse
than interpolating the refined cells on bare fields, crops and forest.

The TIN (tin_dem.py) suits sparse points, which it interpolates between; a dense cloud has several points
per cell, whose median resists mismatches and follows height steps within a cell's width.

Reference: P. J. Rousseeuw, C. Croux, "Alternatives to the median absolute deviation", JASA 88(424), 1993
(1.4826 MAD); the standard error of the median, sqrt(pi / 2) s / sqrt(n), for normal errors."""
import numpy as np

#: m: the spread below which the outlier test does not tighten (quantised or identical heights)
MIN_SPREAD = 0.05
MEDIAN_SE = np.sqrt(np.pi / 2.0)


def _group_medians(key, values):
    """(keys, medians, counts) of `values` grouped by `key` (both 1-D)."""
    order = np.lexsort((values, key))
    k, v = key[order], values[order]
    keys, start, counts = np.unique(k, return_index=True, return_counts=True)
    lo, hi = start + (counts - 1) // 2, start + counts // 2
    return keys, 0.5 * (v[lo] + v[hi]), counts


def cells_on_grid(x, y, z, sigma, grid, k=3.0, own=None, tier=None, fallback=True):
    """(heights, count, precision, removed) on `grid` (tin_grid.Grid) from points x, y, z (and sigma_h, or
    None; and their `tier`, or None: all 0) in its CRS (module docstring); `own(x, y)`: the points this grid
    owns (a tile's), default all."""
    x, y, z = (np.asarray(v, float) for v in (x, y, z))
    col = np.floor((x - grid.x0) / grid.cell).astype(np.int64)
    row = np.floor((grid.y0 - y) / grid.cell).astype(np.int64)
    # the last column and row hold the points on the grid's far edges (as dem_tiles' tile owners)
    col[(col == grid.cols) & (x <= grid.x0 + grid.cols * grid.cell)] = grid.cols - 1
    row[(row == grid.rows) & (y >= grid.y0 - grid.rows * grid.cell)] = grid.rows - 1
    use = np.isfinite(z) & (col >= 0) & (row >= 0) & (col < grid.cols) & (row < grid.rows)
    if own is not None:
        use &= own(x, y)
    if tier is not None:
        tier = np.asarray(tier)
        use &= fallback | (tier == 0)
    key = (row * grid.cols + col)[use]
    z = z[use]
    s = None if sigma is None else np.asarray(sigma, float)[use]
    if tier is not None and key.size:
        tier = tier[use]
        best = np.full(grid.rows * grid.cols, np.iinfo(np.int64).max)
        np.minimum.at(best, key, tier.astype(np.int64))
        first = tier == best[key]
        key, z = key[first], z[first]
        s = None if s is None else s[first]
    heights = np.full((grid.rows, grid.cols), np.nan, np.float32)
    count = np.zeros((grid.rows, grid.cols), np.int32)
    precision = np.full((grid.rows, grid.cols), np.nan, np.float32)
    if key.size == 0:
        return heights, count, precision, 0
    keys, median, _ = _group_medians(key, z)
    slot = np.searchsorted(keys, key)
    dev = np.abs(z - median[slot])
    removed = 0
    if k > 0:
        _, mad, _ = _group_medians(key, dev)
        keep = dev <= k * np.maximum(1.4826 * mad[slot], MIN_SPREAD)
        removed = int((~keep).sum())
        key, z, dev = key[keep], z[keep], dev[keep]
        s = None if s is None else s[keep]
        keys, median, _ = _group_medians(key, z)
        slot = np.searchsorted(keys, key)
        dev = np.abs(z - median[slot])
    _, mad, n = _group_medians(key, dev)
    spread = np.where(n >= 3, 1.4826 * mad, np.nan)
    if s is not None and np.isfinite(s).all():
        spread = np.sqrt(np.bincount(slot, s * s, len(keys)) / n)
    r, c = np.divmod(keys, grid.cols)
    heights[r, c] = median
    count[r, c] = n
    precision[r, c] = MEDIAN_SE * spread / np.sqrt(n)
    return heights, count, precision, removed
