"""The one tiling of a raster, used by both matchers and the orthorectification.

A raster of cols x rows px is cut into squares of `tile` px on a grid anchored at its corner: tile
(i, j) covers columns [i tile, min((i + 1) tile, cols)) and rows [j tile, min((j + 1) tile, rows)),
so the last tile of a row or a column holds the remainder. A tile's box depends only on its index and
the tile size, never on how many tiles there are: a tile's result is the same whatever part of the
scene is processed, and a tile can be named, retried or sent elsewhere by its index.

Boxes are (x0, y0, x1, y1) in pixels, GDAL's convention (pixel (i, j) has its centre at (x0 + j + 0.5,
y0 + i + 0.5)), ordered row by row. Failure mode: InputError for a tile size below 1 px. `cell_blocks` groups points by
the same blocks of a grid."""

import numpy as np

from .errors import InputError


def tile_grid(size, tile):
    """Boxes (x0, y0, x1, y1) of the tiles of a raster of `size` = (cols, rows) px, row by row."""
    cols, rows = (int(v) for v in size)
    tile = int(tile)
    if tile < 1:
        raise InputError(f"the tile size must be at least 1 px, got {tile}")
    return [
        (x0, y0, min(x0 + tile, cols), min(y0 + tile, rows))
        for y0 in range(0, rows, tile)
        for x0 in range(0, cols, tile)
    ]


def cell_blocks(col, row, shape, block):
    """The indices of the points at fractional cell positions (col, row) of a grid of `shape` (rows, cols) in
    each `block` x `block` cell block that holds some (NaN or off the grid: in none), so that points spread
    over a large grid are served one block at a time."""
    rows, cols = shape
    with np.errstate(invalid="ignore"):
        col, row = np.asarray(col, float), np.asarray(row, float)
        on = (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)
    key = np.where(on, np.floor(row / block) * (cols // block + 1) + np.floor(col / block), -1)
    order = np.argsort(key, kind="stable")
    values, starts = np.unique(key[order], return_index=True)
    for value, lo, hi in zip(values, starts, np.append(starts[1:], len(order))):
        if value >= 0:
            yield order[lo:hi]
