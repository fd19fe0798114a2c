"""Linear interpolation of a TIN on a regular grid: per-triangle rasterisation in a numba kernel.

Each triangle fills the grid cells whose centres it holds with the barycentric combination of its
vertex values, z = sum_e w_e z_e / sum_e w_e, w_e the signed edge function of the edge opposite
vertex e. Edge functions are evaluated in one canonical direction per edge (lower vertex index
first), so the two triangles of an edge see exactly opposite values: a cell centre on a shared edge
belongs to exactly one of them (the one on the edge's positive side), and no cell between them is
lost to rounding."""

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..crs import MAX_CELLS
from ..errors import InputError


@dataclass(frozen=True)
class Grid:
    """A north-up grid of `cols` x `rows` square cells of size `cell`, top-left corner (x0, y0)."""

    x0: float
    y0: float
    cell: float
    cols: int
    rows: int

    @property
    def geotransform(self):
        return (self.x0, self.cell, 0.0, self.y0, 0.0, -self.cell)

    @property
    def shape(self):
        return self.rows, self.cols

    def centres(self):
        """(x, y) of the cell centres, arrays of shape (rows, cols)."""
        return np.meshgrid(
            self.x0 + (np.arange(self.cols) + 0.5) * self.cell, self.y0 - (np.arange(self.rows) + 0.5) * self.cell
        )

    def to_cells(self, x, y):
        """Grid coordinates (u, v) with the centre of cell (row i, col j) at (j, i)."""
        return (np.asarray(x) - self.x0) / self.cell - 0.5, (self.y0 - np.asarray(y)) / self.cell - 0.5

    @classmethod
    def covering(cls, x, y, cell):
        """The grid of `cell`-sized cells aligned on multiples of `cell` that covers the points."""
        if not (cell > 0 and math.isfinite(cell)):
            raise InputError(f"the cell size must be a positive number of CRS units, not {cell}")
        x0, x1 = math.floor(np.min(x) / cell) * cell, math.ceil(np.max(x) / cell) * cell
        y0, y1 = math.floor(np.min(y) / cell) * cell, math.ceil(np.max(y) / cell) * cell
        cols, rows = max(round((x1 - x0) / cell), 1), max(round((y1 - y0) / cell), 1)
        if cols * rows > MAX_CELLS:  # before any array; the steps' crs.check_grid_cells names the unit
            raise InputError(f"a {cols} x {rows} grid is too large: choose a larger cell size than {cell}")
        return cls(float(x0), float(y1), float(cell), int(cols), int(rows))


@njit(cache=True, nogil=True)
def _edge(u, v, p, q, pu, pv):
    """Edge function of the canonical edge (min(p, q) -> max(p, q)) at (pu, pv): > 0 on its left."""
    if p > q:
        p, q = q, p
    return (u[q] - u[p]) * (pv - v[p]) - (v[q] - v[p]) * (pu - u[p])


@njit(cache=True, nogil=True)
def rasterize_kernel(u, v, values, triangles, use, out):
    """Fill out[k, i, j] with the linear interpolation of values[:, k] in the triangle holding the cell
    centre (j, i) (grid coordinates u, v of the vertices); cells outside every used triangle keep
    their value."""
    bands, rows, cols = out.shape
    opposite = np.empty(3, np.int64)
    first = np.empty(3, np.int64)
    second = np.empty(3, np.int64)
    side = np.empty(3)
    w = np.empty(3)
    for t in range(triangles.shape[0]):
        if not use[t]:
            continue
        degenerate = False
        for e in range(3):
            opposite[e] = triangles[t, e]
            first[e] = triangles[t, (e + 1) % 3]
            second[e] = triangles[t, (e + 2) % 3]
            s = _edge(u, v, first[e], second[e], u[opposite[e]], v[opposite[e]])
            if s == 0.0:
                degenerate = True
            side[e] = 1.0 if s > 0.0 else -1.0
        if degenerate:
            continue
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        j0 = max(int(math.ceil(min(u[a], u[b], u[c]))), 0)
        j1 = min(int(math.floor(max(u[a], u[b], u[c]))), cols - 1)
        i0 = max(int(math.ceil(min(v[a], v[b], v[c]))), 0)
        i1 = min(int(math.floor(max(v[a], v[b], v[c]))), rows - 1)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                inside = True
                for e in range(3):
                    w[e] = _edge(u, v, first[e], second[e], float(j), float(i)) * side[e]
                    if w[e] < 0.0 or (w[e] == 0.0 and side[e] < 0.0):
                        inside = False
                        break
                if not inside:
                    continue
                total = w[0] + w[1] + w[2]
                for k in range(bands):
                    out[k, i, j] = (
                        w[0] * values[opposite[0], k] + w[1] * values[opposite[1], k] + w[2] * values[opposite[2], k]
                    ) / total


def rasterize(x, y, values, triangles, grid, use=None):
    """Linear TIN interpolation of `values` ((n,) or (n, k) at the points (x, y)) on `grid` over the
    triangles (m, 3) where `use` is True (all by default). Returns (rows, cols) or (k, rows, cols)
    float64, NaN outside the used triangles."""
    values = np.asarray(values, float)
    flat = values.ndim == 1
    values = np.ascontiguousarray(values.reshape(len(x), -1))
    u, v = grid.to_cells(np.asarray(x, float), np.asarray(y, float))
    triangles = np.ascontiguousarray(triangles, np.int64)
    use = np.ones(len(triangles), bool) if use is None else np.ascontiguousarray(use, bool)
    out = np.full((values.shape[1], grid.rows, grid.cols), np.nan)
    rasterize_kernel(np.ascontiguousarray(u), np.ascontiguousarray(v), values, triangles, use, out)
    return out[0] if flat else out
