"""The simulator's ground grids, tile by tile: every grid-sized array (DTM, DSM, land cover,
radiance) lives in a `.npy` file of a work folder (simulate_scene), or in memory where no folder is
given (tests), and
every kernel runs on a tile of at most TILE x TILE cells plus the margin its neighbourhood needs.
So a full-size scene (60 km at 5 m: about 14 000 x 14 000 cells per grid) keeps a few windows in
memory, never a grid (disk_array.DiskArray: mapped only for the slice read or written)."""

import os

import numpy as np

from ..disk_array import DiskArray
from ..tiling import tile_grid

TILE = 2048  # ground tile side, cells


def windows(shape, tile=TILE):
    """The tiles of tiling.tile_grid over a `shape` (rows, cols) grid, as array windows (i0, i1, j0, j1)."""
    return [(y0, y1, x0, x1) for x0, y0, x1, y1 in tile_grid((shape[1], shape[0]), tile)]


def grown(window, shape, top, bottom=None, left=None, right=None):
    """`window` (i0, i1, j0, j1) grown by the given margins in cells (bottom, left and right default
    to top), clipped to the grid: (outer window, inner slices of the tile within the outer one)."""
    bottom = top if bottom is None else bottom
    left = top if left is None else left
    right = left if right is None else right
    i0, i1, j0, j1 = window
    rows, cols = shape
    a0, a1 = max(i0 - top, 0), min(i1 + bottom, rows)
    b0, b1 = max(j0 - left, 0), min(j1 + right, cols)
    return (a0, a1, b0, b1), (slice(i0 - a0, i1 - a0), slice(j0 - b0, j1 - b0))


def cut(array, window):
    """The cells of `window` (i0, i1, j0, j1) as an in-memory array."""
    i0, i1, j0, j1 = window
    return np.asarray(array[i0:i1, j0:j1])


def grid_array(folder, name, shape, dtype):
    """A grid-shaped array: in memory where `folder` is None, else a DiskArray `<folder>/<name>.npy`."""
    if folder is None:
        return np.empty(shape, dtype)
    return DiskArray(os.path.join(folder, f"{name}.npy"), shape, dtype, "the simulator's ground grids")


def release(*arrays):
    """Remove the files of DiskArrays no longer needed (in-memory arrays are left to the collector)."""
    for array in arrays:
        if isinstance(array, DiskArray):
            os.remove(array.path)


def value_range(array, shape, tile=TILE):
    """(min, max) of a grid array, tile by tile."""
    low, high = np.inf, -np.inf
    for window in windows(shape, tile):
        part = cut(array, window)
        low, high = min(low, float(part.min())), max(high, float(part.max()))
    return low, high
