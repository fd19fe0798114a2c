"""The one tiling of a raster, used by both matchers and the orthorectification.

A raster of cols x rows px is cut into squares of `tile` px on a grid anchored at its corner: tile
(i, j) covers columns [i tile, min((i + 1) tile, cols)) and rows [j tile, min((j + 1) tile, rows)),
so the last tile of a row or a column holds the remainder. A tile's box depends only on its index and
the tile size, never on how many tiles there are: a tile's result is the same whatever part of the
scene is processed, and a tile can be named, retried or sent elsewhere by its index.

Boxes are (x0, y0, x1, y1) in pixels, GDAL's convention (pixel (i, j) has its centre at (x0 + j + 0.5,
y0 + i + 0.5)), ordered row by row. Failure mode: InputError for a tile size below 1 px."""
from .errors import InputError


def tile_grid(size, tile):
    """Boxes (x0, y0, x1, y1) of the tiles of a raster of `size` = (cols, rows) px, row by row."""
    cols, rows = (int(v) for v in size)
    tile = int(tile)
    if tile < 1:
        raise InputError(f"the tile size must be at least 1 px, got {tile}")
    return [(x0, y0, min(x0 + tile, cols), min(y0 + tile, rows))
            for y0 in range(0, rows, tile) for x0 in range(0, cols, tile)]
