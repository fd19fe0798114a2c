"""Ray casting against a scene's whole DSM one window at a time (render.py casts against a DSM held
in memory; a full-size scene's DSM is a file of several GB, disk_array.DiskArray).

A batch of rays can only meet the surface between the heights hmax + 5 m and hmin - 5 m where
render.ray_ground cuts it (plus REFINE_M of refinement). Their ground points at those two heights
(acquisition.ray_at_height) bound, with WINDOW_MARGIN cells, the window of the DSM they can cross.
The window's Surface keeps the whole grid's height range and osculating sphere, so every hit equals
the whole grid's (up to the rounding of the window's origin, 1e-15 degrees). Rays whose window
reaches the grid's edge may leave the grid, as they would on the whole grid."""

import math

import numpy as np

from ..errors import GeometryError
from .acquisition import ray_at_height
from .render import REFINE_M, Surface, grid_sphere
from .tiles import cut

WINDOW_MARGIN = 3  # cells around the rays' ground points at the cutting heights
CHUNK = 1024  # detectors per ray-casting chunk of a band of lines
EDGE_STEP = 128  # px between the border rays that bound a chunk's window


class TiledSurface:
    """The DSM `dsm` (an array or disk_array.DiskArray) on `grid`, with its height range (hmin, hmax)."""

    def __init__(self, grid, dsm, height_range):
        self.grid, self.dsm = grid, dsm
        self.hmin, self.hmax = (float(h) for h in height_range)
        self.sphere = grid_sphere(grid)

    def window(self, pos, direction):
        """(i0, i1, j0, j1): the cells the rays pos + mu direction (n, 3) can cross."""
        xs, ys = [], []
        for h in (self.hmin - 5.0 - REFINE_M, self.hmax + 5.0 + REFINE_M):
            x, y = self.grid.vertex(*ray_at_height(pos, direction, h))
            xs.append(x)
            ys.append(y)
        xs, ys = np.concatenate(xs), np.concatenate(ys)
        if not (np.isfinite(xs).all() and np.isfinite(ys).all()):
            raise GeometryError("a line of sight of the simulated images does not reach the ground")
        rows, cols = self.grid.rows, self.grid.cols
        i0 = min(max(int(math.floor(ys.min())) - WINDOW_MARGIN, 0), rows - 2)
        j0 = min(max(int(math.floor(xs.min())) - WINDOW_MARGIN, 0), cols - 2)
        i1 = min(max(int(math.ceil(ys.max())) + WINDOW_MARGIN + 1, i0 + 2), rows)
        j1 = min(max(int(math.ceil(xs.max())) + WINDOW_MARGIN + 1, j0 + 2), cols)
        return i0, i1, j0, j1

    def surface(self, window):
        """The Surface of `window`, cut at the whole grid's heights."""
        return Surface(self.grid.window(*window), cut(self.dsm, window), (self.hmin, self.hmax), self.sphere)

    def trace(self, pos, mat, look):
        """(n, 3) ground (lon, lat, h) of n rays given one by one (render.trace), each in its own window."""
        pos, mat, look = np.atleast_2d(pos), np.atleast_2d(mat), np.atleast_2d(look)
        out = np.empty((len(pos), 3))
        for k in range(len(pos)):
            direction = mat[k].reshape(3, 3) @ look[k]
            out[k] = self.surface(self.window(pos[k : k + 1], direction[None])).trace(
                pos[k : k + 1], mat[k : k + 1], look[k : k + 1]
            )[0]
        return out

    def render(self, pos, mat, look, radiance):
        """Image (lines of pos/mat x detectors of look) of the grid array `radiance` sampled where each
        pixel's ray meets the DSM (render.render), CHUNK detectors at a time; NaN where it misses."""
        out = np.empty((len(pos), len(look)), np.float32)
        lines = np.unique(np.r_[np.arange(0, len(pos), EDGE_STEP), len(pos) - 1])
        for c0 in range(0, len(look), CHUNK):
            c1 = min(c0 + CHUNK, len(look))
            dets = np.unique(np.r_[np.arange(c0, c1, EDGE_STEP), c1 - 1])
            border = [
                (lines, np.full(lines.size, c0)),
                (lines, np.full(lines.size, c1 - 1)),
                (np.zeros(dets.size, int), dets),
                (np.full(dets.size, len(pos) - 1), dets),
            ]
            r = np.concatenate([b[0] for b in border])
            c = np.concatenate([b[1] for b in border])
            direction = np.einsum("nij,nj->ni", mat[r].reshape(-1, 3, 3), look[c])
            window = self.window(pos[r], direction)
            out[:, c0:c1] = self.surface(window).render(pos, mat, look[c0:c1], cut(radiance, window))
        return out
