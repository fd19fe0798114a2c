"""Output cell -> image (col, row) for the indirect method (Heipke et al. 1992, section 4.1) on a coarse grid,
with a stated bound.

The exact chain of a cell centre (x, y) of the output grid is

    (lon, lat) = PROJ(x, y),   h = DEM(lon, lat) (bilinear),   (col, row) = model.ground_to_image(lon, lat, h).

PROJ costs ~0.6 us a point and the rigorous model iterates, so per tile of the output:

1. Nodes: every s-th cell centre (s = 16 to start; the last node at or beyond the tile's last cell) gets
   (lon, lat) from PROJ and (col, row) from the model at two heights h0, h1, the lowest and highest DEM
   heights under the tile: a local model linear in h (like an RPC's H terms) and bilinear in x, y.
2. Cells: lon, lat and the image points c0 (at h0) and c1 (at h1) are interpolated bilinearly from the
   four nodes around the cell; h = DEM(lon, lat); (col, row) = c0 + t (c1 - c0), t = (h - h0) / (h1 - h0).
   The DEM varies within a coarse cell, but it is read per cell: only smooth functions are interpolated.
3. Error bound. A cell's error is (1 - t) e0 + t e1 + q(t) + S e_ll, with e0, e1 the bilinear errors of
   c0, c1, q the departure of the model from linearity in h, e_ll the error (m) of the interpolated lon/lat
   and S its effect on (col, row): S = g + v slope (g the image scale in px/m, v = |c1 - c0| / (h1 - h0) the
   height parallax in px/m, slope the DEM's steepest gradient under the tile). Over a coarse cell the
   mapping is quadratic to high order; bilinear interpolation is exact at the nodes and its error then
   peaks at a cell's centre or edge midpoints, and q(t) = 4 t (1 - t) q(1/2) peaks at mid-height. So the
   lattice of step s/2 (the nodes, edge midpoints and centres) is computed exactly at h0, h1 and
   (h0 + h1) / 2 and

       bound = max(|e0|, |e1|) + max |q(1/2)| + max(e_ll) max(S)       (px, Euclidean in col, row)

   If bound > max_error, s is halved (the s/2 lattice becomes the nodes) until it holds; at s = 1 every
   cell is computed exactly (bound 0). The bound is achieved, not assumed: each tile reports its own.

Cells where the DEM has no height, or a node has no image point (outside the model's domain), are NaN."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ..errors import InputError
from ..geodesy import metres_per_degree

#: first coarse step (cells) tried per tile
START_STEP = 16


@njit(cache=True, nogil=True)
def bilinear_nodes(nodes, u, v, out):
    """Bilinear interpolation of node values nodes (k, n_u, n_v) at fractional node coordinates u (rows),
    v (columns) (n,): out (k, n); the last node row/column closes the last interval."""
    nu, nv = nodes.shape[1], nodes.shape[2]
    for p in range(u.size):
        a = min(int(u[p]), nu - 2)
        b = min(int(v[p]), nv - 2)
        fa = u[p] - a
        fb = v[p] - b
        for k in range(nodes.shape[0]):
            out[k, p] = (nodes[k, a, b] * (1.0 - fb) + nodes[k, a, b + 1] * fb) * (1.0 - fa) + (
                nodes[k, a + 1, b] * (1.0 - fb) + nodes[k, a + 1, b + 1] * fb
            ) * fa


@dataclass
class TileMap:
    """Image coordinates of a window of output cells (NaN where undefined) and the ground they come from;
    `step`: coarse step used (1 = exact per cell); `bound`: achieved error bound (px)."""

    col: np.ndarray
    row: np.ndarray
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    step: int
    bound: float


class Relief(NamedTuple):
    """The DEM under a tile: the heights h0 < h1 the nodes are mapped at and the steepest slope (m/m)."""

    h0: float
    h1: float
    slope: float


class TileMapper:
    """Maps windows of `grid` into the image of `model` over `dem` (module docstring)."""

    def __init__(self, model, dem, grid, max_error=0.01, start_step=START_STEP):
        if not max_error > 0:
            raise InputError(f"the error bound of the coarse-grid interpolation must be positive, got {max_error}")
        if start_step < 1 or start_step & (start_step - 1):
            raise InputError(f"the coarse step must be a power of 2, got {start_step}")
        self.model, self.dem, self.grid = model, dem, grid
        self.max_error, self.start_step = float(max_error), int(start_step)

    def exact(self, row0, col0, rows, cols):
        """TileMap of the exact chain for every cell of the window (the reference; bound 0)."""
        i, j = np.mgrid[row0 : row0 + rows, col0 : col0 + cols]
        lon, lat = self.grid.to_lonlat(*self.grid.centres(i, j))
        h = self.dem.height(lon, lat)
        col, row = self._image(lon, lat, h)
        return TileMap(col, row, lon, lat, h, 1, 0.0)

    def _image(self, lon, lat, h):
        ok = np.isfinite(h)
        col, row = np.full(h.shape, np.nan), np.full(h.shape, np.nan)
        if ok.any():
            col[ok], row[ok] = self.model.ground_to_image(lon[ok], lat[ok], h[ok])
        return col, row

    def _lattice(self, row0, col0, n_u, n_v, step, heights):
        """Exact values on the lattice of `step` from the window's first cell: (lon, lat, image points
        (len(heights), 2, n_u, n_v))."""
        i, j = np.mgrid[0:n_u, 0:n_v] * step
        lon, lat = self.grid.to_lonlat(*self.grid.centres(row0 + i, col0 + j))
        image = np.empty((len(heights), 2) + lon.shape)
        for k, h in enumerate(heights):
            image[k] = self.model.ground_to_image(lon, lat, np.full(lon.shape, h))
        return lon, lat, image

    def _height_range(self, lon, lat):
        """(min, max, steepest slope m/m) of the DEM cells under the lon/lat extent (one cell margin)."""
        lon0, dlon, _, lat0, _, dlat = self.dem.geotransform
        rows, cols = self.dem.shape
        c = (np.array([np.nanmin(lon), np.nanmax(lon)]) - lon0) / dlon
        r = (np.array([np.nanmax(lat), np.nanmin(lat)]) - lat0) / dlat
        c0, c1 = max(int(math.floor(c[0])) - 1, 0), min(int(math.ceil(c[1])) + 1, cols)
        r0, r1 = max(int(math.floor(r[0])) - 1, 0), min(int(math.ceil(r[1])) + 1, rows)
        window = self.dem.heights[r0:r1, c0:c1]
        if c1 <= c0 or r1 <= r0 or not np.isfinite(window).any():
            return None
        slope = 0.0
        if min(window.shape) >= 2:
            me, mn = metres_per_degree(float(np.nanmean(lat)))
            gy, gx = np.gradient(window, abs(dlat) * mn, dlon * me)
            g = np.hypot(gx, gy)
            slope = float(np.nanmax(g)) if np.isfinite(g).any() else 0.0
        return float(np.nanmin(window)), float(np.nanmax(window)), slope

    def tile(self, row0, col0, rows, cols):
        """TileMap of the window (row0, col0, rows, cols) by the coarse-grid scheme of the module docstring."""
        step = self.start_step
        n_u, n_v = max(-(-(rows - 1) // step), 1) + 1, max(-(-(cols - 1) // step), 1) + 1
        lon, lat = self.grid.to_lonlat(
            *self.grid.centres(
                row0 + np.array([0, 0, (n_u - 1) * step, (n_u - 1) * step]), col0 + np.array([0, (n_v - 1) * step] * 2)
            )
        )
        found = self._height_range(lon, lat)
        if found is None:
            nan = np.full((rows, cols), np.nan)
            return TileMap(nan, nan.copy(), nan.copy(), nan.copy(), nan.copy(), step, 0.0)
        h0, h1, slope = found
        h1 = max(h1, h0 + 1.0)
        relief = Relief(h0, h1, slope)
        nodes = self._lattice(row0, col0, n_u, n_v, step, (h0, h1))
        while step > 1:
            bound = self._bound(row0, col0, n_u, n_v, step, nodes, relief)
            if bound <= self.max_error:
                return self._interpolate(rows, cols, step, nodes, h0, h1, bound)
            step //= 2
            n_u, n_v = 2 * n_u - 1, 2 * n_v - 1
            nodes = self._lattice(row0, col0, n_u, n_v, step, (h0, h1))
        return self.exact(row0, col0, rows, cols)

    def _bound(
        self,
        row0: int,
        col0: int,
        n_u: int,
        n_v: int,
        step: int,
        nodes: tuple[np.ndarray, np.ndarray, np.ndarray],
        relief: Relief,
    ) -> float:
        """Error bound (px) of interpolating from the nodes (lon, lat, image points at h0 and h1) of `step`,
        from the exact lattice of step / 2, at the heights and slope of `relief`."""
        h0, h1, slope = relief
        lon, lat, image = nodes
        fine_lon, fine_lat, exact = self._lattice(
            row0, col0, 2 * n_u - 1, 2 * n_v - 1, step // 2, (h0, h1, 0.5 * (h0 + h1))
        )
        u, v = (a.ravel() * 0.5 for a in np.mgrid[0 : 2 * n_u - 1, 0 : 2 * n_v - 1])
        values = np.ascontiguousarray(np.concatenate([lon[None], lat[None], image.reshape(4, n_u, n_v)]))
        out = np.empty((6, u.size))
        bilinear_nodes(values, u, v, out)
        e_h = np.hypot(out[2:6:2] - exact[:2, 0].reshape(2, -1), out[3:6:2] - exact[:2, 1].reshape(2, -1))
        q = np.hypot(*(0.5 * (exact[0] + exact[1]) - exact[2]))
        me, mn = metres_per_degree(fine_lat.ravel())
        e_ll = np.hypot((out[0] - fine_lon.ravel()) * me, (out[1] - fine_lat.ravel()) * mn)
        node_me, node_mn = metres_per_degree(lat)
        g = max(self._scale(lon, lat, image[0], node_me, node_mn))
        par = np.hypot(*(image[1] - image[0])) / (h1 - h0)
        bound = np.nanmax(e_h) + np.nanmax(q) + np.nanmax(e_ll) * (g + np.nanmax(par) * slope)
        return float(bound) if np.isfinite(bound) else math.inf

    @staticmethod
    def _scale(lon, lat, image, me, mn):
        """Largest image scale (px/m) between neighbouring nodes, along rows and along columns."""
        out = []
        for axis in (0, 1):
            px = np.hypot(np.diff(image[0], axis=axis), np.diff(image[1], axis=axis))
            metres = np.hypot(
                np.diff(lon, axis=axis) * me[: lon.shape[0] - 1 + axis, : lon.shape[1] - axis],
                np.diff(lat, axis=axis) * mn[: lon.shape[0] - 1 + axis, : lon.shape[1] - axis],
            )
            ratio = px / metres
            out.append(float(np.nanmax(ratio)) if np.isfinite(ratio).any() else 0.0)
        return out

    def _interpolate(self, rows, cols, step, nodes, h0, h1, bound):
        lon, lat, image = nodes
        n_u, n_v = lon.shape
        values = np.ascontiguousarray(np.concatenate([lon[None], lat[None], image.reshape(4, n_u, n_v)]))
        u, v = np.mgrid[0:rows, 0:cols] / float(step)
        out = np.empty((6, rows * cols))
        bilinear_nodes(values, u.ravel(), v.ravel(), out)
        h = self.dem.height(out[0], out[1])
        t = (h - h0) / (h1 - h0)
        col = out[2] + t * (out[4] - out[2])
        row = out[3] + t * (out[5] - out[3])
        shape = (rows, cols)
        return TileMap(
            col.reshape(shape),
            row.reshape(shape),
            out[0].reshape(shape),
            out[1].reshape(shape),
            h.reshape(shape),
            step,
            bound,
        )
