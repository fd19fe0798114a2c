"""Dense image-2 positions of a lattice of image-1 points in one tile: epipolar grid, epipolar images,
semi-global disparity, and the disparity read back at the lattice.

For the tile `box` of image 1 (x0, y0, x1, y1 px) and a pair (image 1, image 2):
1. the tile's EpipolarGrid over the height range (epipolar.py), with a margin of the census window;
2. both epipolar images (resample.py) from the images as matching sees them: the finer one low-passed
   to the coarser one's resolution (matching.resolution.adapt_resolution);
3. the disparity over the grid's disparity range at the range's heights, widened by 2 px (sgm.py);
4. the lattice: image-1 pixel centres x = x0 + 0.5 + i step, y = y0 + 0.5 + j step inside the box; each
   node's epipolar (u, v) (EpipolarGrid.epipolar1), its disparity d bilinear between the four samples
   around it (only where the four are defined and span at most `max_spread` px: a node between two
   surfaces takes no disparity), and its image-2 position Q(u + d, v) (EpipolarGrid.image2).

Masked pixels (matching.imagery: nodata, the GDAL mask, saturated; images given as paths or arrays mask their
saturated pixels) are NaN in the images read: the low-pass and the epipolar resampling spread them over their
supports (no grey value is interpolated across a nodata edge or a saturated patch's), the census gives no code
to a window that holds one, and the semi-global matcher keeps no disparity where the conjugate may be a
candidate without a code (sgm.py, scored candidates). A node yields no point where one of these reaches it.

Image positions are GDAL's. A node without a disparity is NaN. The epipolar images and the cost volume are
the tile's: memory follows the tile and its disparity range."""

import math

import numpy as np

from ..matching.imagery import as_image
from ..matching.pair_geometry import ImagePair
from ..matching.params import GrowParams
from ..matching.resolution import adapt_resolution
from ..matching.seeds import automatic_seeds
from .epipolar import disparity_range, epipolar_grid
from .resample import epipolar_image
from .sgm import disparity

DISPARITY_MARGIN = 2.0  # px beyond the height range's disparities (the V fit needs a neighbour)
MIN_SEEDS = 5  # seeds a tile needs to correct its rows and narrow its disparity range
SEED_MARGIN = 0.25  # the seeds' disparity span widened by this fraction of it on each side ...
SEED_MARGIN_PX = 10.0  # ... and by at least this many px


def lattice(box, step):
    """Image-1 lattice nodes (x, y) of the tile box (pixel centres every `step` px from its corner)."""
    x0, y0, x1, y1 = (int(v) for v in box)
    xs = x0 + 0.5 + np.arange(0, x1 - x0, step)
    ys = y0 + 0.5 + np.arange(0, y1 - y0, step)
    x, y = np.meshgrid(xs, ys)
    return x.ravel(), y.ravel()


def sample_disparity(disp, u, v, max_spread):
    """Bilinear disparity at epipolar array positions (u, v) (column, row of `disp`), NaN where one of the
    four samples is undefined or they span more than max_spread px."""
    rows, cols = disp.shape
    j = np.floor(u).astype(int)
    i = np.floor(v).astype(int)
    inside = (j >= 0) & (i >= 0) & (j < cols - 1) & (i < rows - 1)
    j, i = np.where(inside, j, 0), np.where(inside, i, 0)
    d = np.stack([disp[i, j], disp[i, j + 1], disp[i + 1, j], disp[i + 1, j + 1]])
    tu, tv = u - j, v - i
    out = (1 - tv) * ((1 - tu) * d[0] + tu * d[1]) + tv * ((1 - tu) * d[2] + tu * d[3])
    with np.errstate(invalid="ignore"):
        ok = inside & np.isfinite(d).all(axis=0) & (d.max(axis=0) - d.min(axis=0) <= max_spread)
    return np.where(ok, out, np.nan)


def tile_seeds(image1, image2, model1, model2, box, height_range, grid):
    """The tile's sparse matches (seeds.automatic_seeds over the whole height range: Foerstner points, NCC
    along the predicted path +- 3 px across, LSM) in epipolar coordinates: (u1, v1, u2, v2) arrays."""
    seeds = automatic_seeds(ImagePair(image1, image2, model1, model2), GrowParams(), height_range, box=box)
    u1, v1 = grid.epipolar1(seeds["x1"], seeds["y1"])
    u2, v2 = grid.epipolar2(seeds["x2"], seeds["y2"])
    good = np.isfinite(u1) & np.isfinite(v1) & np.isfinite(u2) & np.isfinite(v2)
    return u1[good], v1[good], u2[good], v2[good]


def match_pair_tile(image1, image2, model1, model2, box, height_range, params):
    """(x1, y1, x2, y2, info): the tile's lattice nodes and their image-2 positions (module docstring)
    with DenseParams `params`, NaN where a node has none; info: the grid, the row offset, the disparity
    range and the seeds."""
    x1, y1 = lattice(box, params.step)
    image1, image2 = as_image(image1, saturation=True), as_image(image2, saturation=True)
    a1, a2 = adapt_resolution(image1, image2, model1, model2, GrowParams(), height_range)
    grid = epipolar_grid(model1, model2, box, height_range, step=params.grid_step, margin=params.sgm.census_radius + 2)
    span = disparity_range(model1, model2, grid, height_range)
    su1, sv1, su2, sv2 = tile_seeds(image1, image2, model1, model2, box, height_range, grid)
    info = {"grid": grid, "seeds": len(su1), "row_offset": 0.0, "d_range": None}
    if span is None:
        return x1, y1, np.full(x1.size, np.nan), np.full(x1.size, np.nan), info
    if len(su1) >= MIN_SEEDS:
        # the orientation's error across the rows, and the disparities of the tile's terrain
        info["row_offset"] = float(np.median(sv2 - sv1))
        sd = su2 - su1
        widen = max(SEED_MARGIN_PX, SEED_MARGIN * float(sd.max() - sd.min()))
        span = (max(span[0], float(sd.min()) - widen), min(span[1], float(sd.max()) + widen))
    d_range = (math.floor(span[0] - DISPARITY_MARGIN), math.ceil(span[1] + DISPARITY_MARGIN))
    info["d_range"] = d_range
    offset = info["row_offset"]
    epi1 = epipolar_image(a1, grid.p, grid.step)
    epi2 = epipolar_image(a2, shifted_rows(grid, offset), grid.step)
    if not np.isfinite(epi1).any() or not np.isfinite(epi2).any():
        return x1, y1, np.full(x1.size, np.nan), np.full(x1.size, np.nan), info
    disp = disparity(epi1, epi2, d_range, params.sgm)
    u, v = grid.epipolar1(x1, y1)
    d = sample_disparity(disp, u - grid.u0, v - grid.v0, params.max_spread)
    x2, y2 = grid.image2(u + d, v + offset)
    return x1, y1, np.where(np.isfinite(d), x2, np.nan), np.where(np.isfinite(d), y2, np.nan), info


def shifted_rows(grid, offset):
    """Image-2 nodes of the grid moved by `offset` epipolar rows (Q(u, v + offset) at every node)."""
    if offset == 0.0:
        return grid.q
    rows, cols = grid.q.shape[:2]
    v, u = np.meshgrid(
        grid.v0 + np.arange(rows) * grid.step + offset, grid.u0 + np.arange(cols) * grid.step, indexing="ij"
    )
    return np.stack(grid.image2(u, v), axis=-1)
