"""A per-cell DSM of a dense point cloud: each cell's height is a robust fusion of the points that fall in it.

For the points of one cell (x0 + c cell <= x < x0 + (c + 1) cell, likewise in y), with median m and
MAD = median |z - m|:
- outliers: points with |z - m| > k max(1.4826 MAD, MIN_SPREAD) are dropped (k = 0: none; a statistical
  filter within the cell: a mismatch lands metres off the surface its neighbours agree on);
- height: the median of the points kept;
- counts: the points kept;
- precision (m): where every point the grid uses has its sigma_h, the RMS of the kept points' sigma_h. The points
  of one cell are not independent: a cell is smaller than a matching template (a dense point per pixel, 19 px
  templates), so neighbouring points measured nearly the same template and their errors are nearly one error;
  their median is no better than one of them (studies/README.md#dense_cell_precision). Otherwise (no sigma_h), the
  standard error of a median of independent points, 1.2533 s / sqrt(n), s = 1.4826 MAD of the kept points
  (n >= 3; NaN below).
Points on the grid's far edges belong to its last column and row.

Radius (cells, r >= 0; rasterization, not gap filling): a cell with no point of its own takes the points of
the nearest ring of cells around it that has some, up to r cells away (Chebyshev distance), with the same
median, outlier test and precision. A dense cloud with about one point per pixel leaves cells of the pixel's
size empty by sampling alone (points fall two to a cell here, none there); CARS's rasterization likewise
reads the points within one cell (its dsm_radius). The ring each cell used is returned: 0 its own points.
A cell with no point within r is NaN (a gap), never filled here.

Tiers: where the points carry a `tier` (THREE_RAYS: refined and intersected from three or more rays, or any
sparse point; TWO_RAYS: refined, two rays; UNREFINED: a dense point LSM left at the semi-global position), a
cell uses only the points of the best tier it has (the tier first, then the ring: a three-ray point a cell away
is preferred to a two-ray one of the cell's own unless the precision rule below says otherwise, and a refined
one to an unrefined one, always); with `fallback` off,
no UNREFINED point is used (such a cell is a gap). studies/dense_fusion.py measures why the unrefined points
come last: their heights are worse than the refined ones' everywhere but in the city, and worse than
interpolating the refined cells on bare fields, crops and forest. Three rays come before two: their wider base
and their redundancy give the better heights (docs/validation.md#dense-peers: the simulated triplet's bare
fields).

The precision rule: where the points carry their sigma_h (every point used), a cell that has refined points of
its own but takes a better tier from the ring around takes its own refined points instead when their precision
(the RMS of their sigma_h) is no worse than the ring's; never its unrefined ones, whose a priori sigma carries no
spread term. A calibrated precision says which of the two measures the cell better; a ring's
points are a cell away, so ties go to the cell's own. Measured in studies/README.md#own_cells_floor: on the
simulated triplets the own cells rise from 73.0 to 73.4 % and from 88.6 to 90.2 %, and no class gets worse.

The TIN (tin_dem.py) suits sparse points, which it interpolates between; a dense cloud has several points
per cell, whose median resists mismatches and follows height steps within a cell's width.

Reference: P. J. Rousseeuw, C. Croux, "Alternatives to the median absolute deviation", JASA 88(424), 1993
(1.4826 MAD); the standard error of the median, sqrt(pi / 2) s / sqrt(n), for normal errors."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from .tin_grid import Grid

#: m: the spread below which the outlier test does not tighten (quantised or identical heights)
MIN_SPREAD = 0.05
MEDIAN_SE = np.sqrt(np.pi / 2.0)
#: the ring of a cell without a height
NO_RING = 255
#: tiers of points (module docstring)
THREE_RAYS, TWO_RAYS, UNREFINED = 0, 1, 2


def point_tiers(rho: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """Each point's tier from the cloud's fields: UNREFINED where its rho is NaN (a dense point LSM left at the
    semi-global position), else TWO_RAYS where it has two rays, else THREE_RAYS."""
    tier = np.where(np.asarray(rays) == 2, TWO_RAYS, THREE_RAYS).astype(np.uint8)
    tier[np.isnan(np.asarray(rho, float))] = UNREFINED
    return tier


def _group_medians(key: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(keys, medians, counts) of `values` grouped by `key` (both 1-D)."""
    order = np.lexsort((values, key))
    k, v = key[order], values[order]
    keys, start, counts = np.unique(k, return_index=True, return_counts=True)
    lo, hi = start + (counts - 1) // 2, start + counts // 2
    return keys, 0.5 * (v[lo] + v[hi]), counts


class Cells(NamedTuple):
    """A per-cell DSM (module docstring) on a grid's (rows, cols)."""

    heights: np.ndarray  # float32, NaN: a gap
    counts: np.ndarray  # int32, the points the cell's height used
    precision: np.ndarray  # float32, m
    removed: int  # points the per-cell outlier test dropped from their own cell
    ring: np.ndarray  # uint8: 0 the cell's own points, r those of the cells r away, NO_RING a gap


class CellSettings(NamedTuple):
    """How a cell fuses its points (module docstring): outliers beyond `k` robust spreads dropped (0: none);
    with `fallback` off, no UNREFINED point is used; a cell without points of its own takes those of the
    nearest ring of cells within `radius` cells."""

    k: float = 3.0
    fallback: bool = True
    radius: int = 0


def cells_on_grid(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    sigma: np.ndarray | None,
    grid: Grid,
    settings: CellSettings = CellSettings(),
    own: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    tier: np.ndarray | None = None,
) -> Cells:
    """Cells on `grid` (tin_grid.Grid) from points x, y, z (and sigma_h, or None; and their `tier`, or None:
    all 0) in its CRS (module docstring) with CellSettings `settings`; `own(x, y)`: the points whose cell
    this grid owns (a tile's), default all. With `sigma` and `tier` (and a radius), the sigmas also choose between
    a cell's own points and the ring's (the precision rule), so they can change the heights."""
    x, y, z = (np.asarray(v, float) for v in (x, y, z))
    radius = int(settings.radius)
    col = np.floor((x - grid.x0) / grid.cell).astype(np.int64)
    row = np.floor((grid.y0 - y) / grid.cell).astype(np.int64)
    owned = np.ones(x.size, bool) if own is None else np.asarray(own(x, y), bool)
    # the last column and row hold the points on the grid's far edges (as dem_tiles' tile owners)
    col[(col == grid.cols) & (x <= grid.x0 + grid.cols * grid.cell) & owned] = grid.cols - 1
    row[(row == grid.rows) & (y >= grid.y0 - grid.rows * grid.cell) & owned] = grid.rows - 1
    use = np.isfinite(z)
    t = np.zeros(x.size, np.int64) if tier is None else np.asarray(tier).astype(np.int64)
    if not settings.fallback:
        use &= t < UNREFINED
    # one kind of precision for the whole grid: the sigmas' only where every point it uses has one
    s = None if sigma is None else np.asarray(sigma, float)
    if s is not None and not np.isfinite(s[use]).all():
        s = None
    points = _Points(row, col, owned, use, z, s)
    cells, _ = _fuse(points, t, radius, settings.k, grid)
    if s is None or tier is None or radius == 0:
        return cells
    # the precision rule (module docstring): in the cells that took the ring's points, their own refined points of
    # any tier, against the ring's better tier
    inside = (row >= 0) & (col >= 0) & (row < grid.rows) & (col < grid.cols)
    candidate = np.zeros(x.size, bool)
    candidate[inside] = cells.ring[row[inside], col[inside]] != 0
    candidate &= use & (t < UNREFINED)
    if not candidate.any():
        return cells
    mine, dropped = _fuse(points._replace(use=candidate), np.zeros_like(t), 0, settings.k, grid)
    take = (cells.ring != 0) & (mine.ring == 0) & (mine.precision <= cells.precision)
    heights, count, precision = (np.where(take, a, b) for a, b in zip(mine[:3], cells[:3]))
    removed = cells.removed + int(dropped[take].sum())  # the ring's cells counted none of their own
    return Cells(heights, count, precision, removed, np.where(take, np.uint8(0), cells.ring))


class _Points(NamedTuple):
    """The points as _fuse reads them: each one's cell (row, col), whether this grid owns it, whether it is used,
    its height and sigma_h (or None)."""

    row: np.ndarray
    col: np.ndarray
    owned: np.ndarray
    use: np.ndarray
    z: np.ndarray
    sigma: np.ndarray | None


def _fuse(points: _Points, t: np.ndarray, radius: int, k: float, grid: Grid) -> tuple[Cells, np.ndarray]:
    """The cells of `points` with tiers `t` (the tier first, then the ring, up to `radius` cells; module docstring),
    and per cell the points of its own the outlier test dropped."""
    row, col, owned, use, z, sigma = points
    index = np.flatnonzero(use)
    # each point offered to the cells within `radius` of its own, ring by ring; rank: tier first, then the ring;
    # an offer to a cell that already has a better rank is dropped at once
    best = np.full(grid.rows * grid.cols, np.iinfo(np.int64).max)
    key_parts: list[np.ndarray] = []
    pick_parts: list[np.ndarray] = []
    rank_parts: list[np.ndarray] = []
    ring_parts: list[np.ndarray] = []
    for distance in range(radius + 1):
        for dr, dc in (
            (a, b)
            for a in range(-distance, distance + 1)
            for b in range(-distance, distance + 1)
            if max(abs(a), abs(b)) == distance
        ):
            r, c = row[index] + dr, col[index] + dc
            ok = (r >= 0) & (c >= 0) & (r < grid.rows) & (c < grid.cols)
            if distance == 0:
                ok &= owned[index]
            key, pick = (r * grid.cols + c)[ok], index[ok]
            rank = t[pick] * (radius + 1) + distance
            better = rank <= best[key]
            key, pick, rank = key[better], pick[better], rank[better]
            for value in np.unique(rank):  # a tier or two: plain assignments, not the slow ufunc.at
                at = key[rank == value]
                best[at] = np.minimum(best[at], value)
            key_parts.append(key)
            pick_parts.append(pick)
            rank_parts.append(rank)
            ring_parts.append(np.full(key.size, distance, np.uint8))
    key, pick, rank = (np.concatenate(v) for v in (key_parts, pick_parts, rank_parts))
    ring = np.concatenate(ring_parts)
    heights = np.full((grid.rows, grid.cols), np.nan, np.float32)
    count = np.zeros((grid.rows, grid.cols), np.int32)
    precision = np.full((grid.rows, grid.cols), np.nan, np.float32)
    source = np.full((grid.rows, grid.cols), NO_RING, np.uint8)
    dropped = np.zeros((grid.rows, grid.cols), np.int64)
    if key.size == 0:
        return Cells(heights, count, precision, 0, source), dropped
    first = rank == best[key]
    key, pick, ring = key[first], pick[first], ring[first]
    z = z[pick]
    s = None if sigma is None else np.asarray(sigma, float)[pick]
    keys, median, _ = _group_medians(key, z)
    slot = np.searchsorted(keys, key)
    dev = np.abs(z - median[slot])
    removed = 0
    if k > 0:
        _, mad, _ = _group_medians(key, dev)
        keep = dev <= k * np.maximum(1.4826 * mad[slot], MIN_SPREAD)
        gone = ~keep & (ring == 0)
        removed = int(gone.sum())
        dropped.flat[:] = np.bincount(key[gone], minlength=dropped.size)
        key, z, dev, ring = key[keep], z[keep], dev[keep], ring[keep]
        s = None if s is None else s[keep]
        keys, median, _ = _group_medians(key, z)
        slot = np.searchsorted(keys, key)
        dev = np.abs(z - median[slot])
    _, mad, n = _group_medians(key, dev)
    if s is not None:
        error = np.sqrt(np.bincount(slot, s * s, len(keys)) / n)
    else:
        error = MEDIAN_SE * np.where(n >= 3, 1.4826 * mad, np.nan) / np.sqrt(n)
    r, c = np.divmod(keys, grid.cols)
    heights[r, c] = median
    count[r, c] = n
    precision[r, c] = error
    source.flat[key] = ring  # a cell's points share their rank, so their ring
    return Cells(heights, count, precision, removed, source), dropped
