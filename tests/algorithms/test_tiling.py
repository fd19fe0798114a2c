"""The one tiling (algorithms/tiling.py) against a plain numpy labelling of every pixel."""

import numpy as np
import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.tiling import tile_grid


@pytest.mark.parametrize("size, tile", [((1000, 700), 256), ((256, 256), 256), ((10, 3), 4), ((5, 9), 100)])
def test_the_tiles_cover_every_pixel_once_row_by_row(size, tile):
    cols, rows = size
    count = np.zeros((rows, cols), int)
    label = np.full((rows, cols), -1)
    for k, (x0, y0, x1, y1) in enumerate(tile_grid(size, tile)):
        count[y0:y1, x0:x1] += 1
        label[y0:y1, x0:x1] = k
    assert (count == 1).all()  # a partition of the raster
    # numpy reference: pixel (i, j) lies in tile (i // tile) * ceil(cols / tile) + j // tile
    ii, jj = np.mgrid[0:rows, 0:cols]
    assert (label == (ii // tile) * -(-cols // tile) + jj // tile).all()


def test_a_tile_is_the_same_box_in_a_larger_raster():
    small = tile_grid((1000, 700), 256)
    large = {box[:2]: box for box in tile_grid((5000, 4000), 256)}
    # every full tile of the smaller raster is the larger raster's tile at the same corner
    full = [b for b in small if b[2] - b[0] == 256 and b[3] - b[1] == 256]
    assert len(full) == 6 and all(large[b[:2]] == b for b in full)


def test_a_tile_size_below_one_pixel_is_refused():
    with pytest.raises(InputError, match="at least 1 px"):
        tile_grid((100, 100), 0)
