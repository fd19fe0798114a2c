"""Region-growing least-squares matching after Otto & Chau, as refined by Hofmann et al.

Seeds are matched by LSM; accepted points enter a priority list ordered by decreasing correlation
coefficient rho. The best point is popped and its four neighbours at distance STEP in image 1
(left, right, up, down) are matched with the popped point's result as initial values (position
and affine transported by STEP); a neighbour enters the list only if it passes the acceptance
criteria (rho > rho_min, error-ellipse semi-major axis < max_ellipse, shift from the initial values
< max_shift, iterations < max_iterations). Every lattice node is matched at most once; the run
stops when the list is empty. The growth of a tile is a numba kernel (region_growing_kernels.py).

The lattice is global: node (m, n) of image 1 lies at (L0 + n STEP, L0 + m STEP) with L0 = half +
0.5 (the first pixel centre with a complete template), so lattices of different seeds and tiles
coincide. Automatic seeds come in two rounds per tile: interest points, one per seeds.CELL px,
grown; then one per GrowParams.reseed_cell px at the nodes the growth has not tried, grown on into
the untried nodes only (the first round's points stay as they were). The second round reaches
parcels without a seed of their own (a CELL px cell keeps only its strongest interest point,
which may lie in another parcel, cut off by nodes that failed); a tile whose first round accepted
nothing (water, cloud) is searched at the second round's density.

The reference image is cut into tiles of `params.tile` px (tiling.tile_grid); a node belongs to
the tile containing it, each tile grows from its own seeds inside windows of both images (image 1:
the tile plus the template; image 2: pair_geometry.search_box of the tile plus a margin), so
memory is bounded by the tile size and tiles run independently (execution.run_tasks: threads over
the nogil kernel, local processes or Dask). Results are merged by lattice index, so they do
not depend on the number of workers.
"""

import math
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..execution import Execution, run_tasks
from ..height_range import HeightRange
from ..progress import ensure, step as progress_step
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .imagery import as_image
from .lsm import LSM_OUT, match_accepted, solver, to_records
from .pair_geometry import ImagePair, local_affine, predict
from .params import GrowParams
from .records import PAIR_DTYPE
from .region_growing_kernels import Accept, Tile, grow_kernel
from .resolution import adapt_resolution
from .seeds import CELL, automatic_seeds, search_margin, seed_operator, seeds_from_points, window_pair


class Lattice:
    """The global lattice of image 1: node (m, n) at (l0 + n step, l0 + m step)."""

    def __init__(self, size, params):
        self.step = int(params.step)
        self.half = params.template // 2
        self.l0 = self.half + 0.5
        self.size = size
        cols, rows = size
        last_x = cols - 0.5 - self.half
        last_y = rows - 0.5 - self.half
        self.ncols = int(math.floor((last_x - self.l0) / self.step)) + 1
        self.nrows = int(math.floor((last_y - self.l0) / self.step)) + 1

    def position(self, m, n):
        return self.l0 + np.asarray(n) * self.step, self.l0 + np.asarray(m) * self.step

    def index_range(self, start, stop, count):
        """Node indices whose position lies in [start, stop) px, clipped to [0, count)."""
        a = max(0, int(math.ceil((start - self.l0) / self.step)))
        b = min(count, int(math.ceil((stop - self.l0) / self.step)))
        return a, b

    def tiles(self, tile):
        """(n_a, n_b, m_a, m_b) node ranges of the tiles of tiling.tile_grid holding nodes, row by row."""
        out = []
        for x0, y0, x1, y1 in tile_grid(self.size, tile):
            n_a, n_b = self.index_range(x0, x1, self.ncols)
            m_a, m_b = self.index_range(y0, y1, self.nrows)
            if n_b > n_a and m_b > m_a:
                out.append((n_a, n_b, m_a, m_b))
        return out


def _check_inputs(image1, image2, model1, model2, params, hr):
    t = params.template
    for name, image in (("image 1", image1), ("image 2", image2)):
        if image.size[0] < t + 2 or image.size[1] < t + 2:
            raise InputError(
                f"{name} ({image.size[0]} x {image.size[1]} px) is smaller than the matching "
                f"template ({t} x {t} px) plus a border; use a larger image or a smaller template"
            )
    cols, rows = image1.size
    gx, gy = np.meshgrid(np.linspace(0, cols, 9), np.linspace(0, rows, 9))
    c2, r2 = image2.size
    for h in np.linspace(hr[0], hr[1], 3):
        with np.errstate(invalid="ignore"):
            x2, y2 = predict(model1, model2, gx.ravel(), gy.ravel(), np.full(gx.size, h))
            inside = (x2 > 0) & (x2 < c2) & (y2 > 0) & (y2 < r2)
        if inside.any():
            return
    raise InputError(
        "the two images do not overlap according to their sensor models (no image-1 point projects "
        f"into image 2 at heights {hr[0]:.0f}..{hr[1]:.0f} m); check the image pair and the models"
    )


def _as_seed_records(seeds):
    seeds = np.asarray(seeds)
    if seeds.dtype.names is None or not {"x1", "y1", "x2", "y2", "a1", "a2", "a4", "a5"} <= set(seeds.dtype.names):
        raise InputError("seeds must be PAIR_DTYPE records (from seeds_from_points or automatic_seeds)")
    seeds = seeds.ravel()
    good = np.isfinite(seeds["x2"]) & np.isfinite(seeds["y2"]) & np.isfinite(seeds["a1"]) & np.isfinite(seeds["a5"])
    return seeds[good]


def _seed_rows(seeds, lattice, n_a, n_b, m_a, m_b, ids):
    """Seed records -> kernel rows at their nearest lattice node of the tile (initial values
    transported by the seed's affine), ordered by decreasing rho then id."""
    nx = n_b - n_a
    n = np.clip(np.rint((seeds["x1"] - lattice.l0) / lattice.step), n_a, n_b - 1).astype(np.int64)
    m = np.clip(np.rint((seeds["y1"] - lattice.l0) / lattice.step), m_a, m_b - 1).astype(np.int64)
    xn, yn = lattice.position(m, n)
    dk = xn - seeds["x1"]
    dl = yn - seeds["y1"]
    a1, a2, a4, a5 = (seeds[k].astype(float) for k in ("a1", "a2", "a4", "a5"))
    rows = np.column_stack(
        [
            (m - m_a) * nx + (n - n_a),
            seeds["x2"] + a1 * dk + a2 * dl,
            seeds["y2"] + a4 * dk + a5 * dl,
            a1,
            a2,
            a4,
            a5,
            ids,
        ]
    )
    order = np.lexsort((ids, -seeds["rho"].astype(float)))
    return np.ascontiguousarray(rows[order])


def seed_stride(params):
    """Seed ids per tile: at least the interest points both rounds of automatic seeds can find in
    a tile (one per cell; 10000 for the default tile and cells)."""
    cells = sum((params.tile // c + 2) ** 2 for c in (CELL, params.reseed_cell) if c)
    return max(10000, cells)


class GrowJob(NamedTuple):
    """What every tile of one match_pair run shares: the (resolution-adapted) images and their models,
    the parameters, the height range, the lattice, the given seeds (PAIR_DTYPE or None) and whether
    automatic seeds are sought."""

    image1: object
    image2: object
    model1: object
    model2: object
    params: GrowParams
    hr: tuple
    lattice: Lattice
    seeds: object
    automatic: bool


def _grow_tile(job, index, box):
    """Region growing of the tile with node ranges `box` (Lattice.tiles), the index-th tile of `job`:
    (PAIR_DTYPE records, LSM attempts, seeds tried)."""
    image1, image2, model1, model2, params, hr, lattice, seeds, automatic = job
    n_a, n_b, m_a, m_b = box
    half, step = lattice.half, lattice.step
    pad = params.widest // 2 + 2
    gx0, gy0 = lattice.position(m_a, n_a)
    nx, ny = n_b - n_a, m_b - m_a
    x_last, y_last = lattice.position(m_b - 1, n_b - 1)
    box1 = (
        int(math.floor(gx0 - pad)),
        int(math.floor(gy0 - pad)),
        int(math.ceil(x_last + pad + 1)),
        int(math.ceil(y_last + pad + 1)),
    )
    margin = search_margin(model1, model2, params, hr, 0.5 * (gx0 + x_last), 0.5 * (gy0 + y_last)) + step
    windows = window_pair(image1, image2, model1, model2, box1, hr, margin)
    win1, ox1, oy1, win2, ox2, oy2 = windows
    empty = np.zeros(0, PAIR_DTYPE)
    if win2.shape[0] < 4 or win2.shape[1] < 4:
        return empty, 0, 0
    parts, ids = [], []
    if seeds is not None:
        n = np.rint((seeds["x1"] - lattice.l0) / step)
        m = np.rint((seeds["y1"] - lattice.l0) / step)
        mine = (
            ((n >= n_a) | (n_a == 0))
            & ((n < n_b) | (n_b == lattice.ncols))
            & ((m >= m_a) | (m_a == 0))
            & ((m < m_b) | (m_b == lattice.nrows))
        )
        parts.append(seeds[mine])
        ids.append(np.flatnonzero(mine))
    first_id = (0 if seeds is None else len(seeds)) + index * seed_stride(params)
    own = (gx0 - 0.5 * step, gy0 - 0.5 * step, x_last + 0.5 * step, y_last + 0.5 * step)
    operator = seed_operator(win1, params) if automatic else None
    if automatic:
        found = automatic_seeds(
            ImagePair(image1, image2, model1, model2), params, hr, box=own, windows=windows, operator=operator
        )
        parts.append(found)
        ids.append(first_id + np.arange(len(found)))
    tile_seeds, ids = np.concatenate(parts), np.concatenate(ids)  # match_pair ensures one source
    _, _, *aff = local_affine(model1, model2, 0.5 * (gx0 + x_last), 0.5 * (gy0 + y_last), 0.5 * (hr[0] + hr[1]))
    prior = np.array([float(v[0]) for v in aff]) if params.model_affine else np.zeros(0)
    if not np.all(np.isfinite(prior)):
        prior = np.zeros(0)
    results = np.full((nx * ny, LSM_OUT), np.nan)
    state = np.zeros(nx * ny, np.int8)
    origin = np.full(nx * ny, -1, np.int64)

    def grow(tile_seeds, seed_ids):
        rows = _seed_rows(tile_seeds, lattice, n_a, n_b, m_a, m_b, seed_ids)
        tile = Tile(
            win1, win2, float(ox1), float(oy1), float(ox2), float(oy2), float(gx0), float(gy0), float(step), nx, ny
        )
        accept = Accept(params.rho_min, params.max_ellipse, params.max_shift, params.max_iterations)
        return grow_kernel(
            tile, rows, solver(params, half), solver(params, params.widest // 2), accept, results, state, origin, prior
        )

    def untried(x1, y1):
        n = np.clip(np.rint((x1 - lattice.l0) / step), n_a, n_b - 1).astype(np.int64) - n_a
        m = np.clip(np.rint((y1 - lattice.l0) / step), m_a, m_b - 1).astype(np.int64) - m_a
        return state[m * nx + n] == 0

    nseeds = len(tile_seeds)
    tries = grow(tile_seeds, ids) if nseeds else 0
    if automatic and params.reseed_cell:  # second round: denser interest points where growth has not been
        check_cancel()  # between the rounds (execution: a cancel reaches a running tile)
        again = automatic_seeds(
            ImagePair(image1, image2, model1, model2),
            params,
            hr,
            box=own,
            windows=windows,
            cell=params.reseed_cell,
            keep=untried,
            operator=operator,
        )
        if len(again):
            tries += grow(again, first_id + len(found) + np.arange(len(again)))
            nseeds += len(again)
    if nseeds == 0:
        return empty, 0, 0
    good = np.flatnonzero(state == 1)
    rec = to_records(*lattice.position(m_a + good // nx, n_a + good % nx), results[good])
    rec["seed"] = origin[good]
    return rec, tries, nseeds


def grow_job(pair: ImagePair, params=None, height_range=None, seeds=None, automatic=None):
    """(GrowJob, tiles: Lattice.tiles) of a match_pair run (its arguments; InputError as it raises), for
    _grow_tile tasks. Every pair with the same image 1 and params has the same tiles."""
    image1, image2, model1, model2 = pair
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    hr = HeightRange.resolve(height_range, model1).bounds
    _check_inputs(image1, image2, model1, model2, params, hr)
    image1, image2 = adapt_resolution(image1, image2, model1, model2, params, hr)
    lattice = Lattice(image1.size, params)
    if seeds is not None:
        seeds = _as_seed_records(seeds)
    automatic = seeds is None if automatic is None else bool(automatic)
    if seeds is None and not automatic:
        raise InputError("region growing needs seeds: give seed points or allow automatic seeds")
    return GrowJob(image1, image2, model1, model2, params, hr, lattice, seeds, automatic), lattice.tiles(
        int(params.tile)
    )


def match_pair(pair: ImagePair, params=None, height_range=None, seeds=None, feedback=None, workers=1, automatic=None):
    """Region-growing LSM of image 1 (reference) into image 2.

    image1, image2: Image or raster path; model1, model2: their sensor models; params: GrowParams;
    height_range: (h_min, h_max) ellipsoidal, or a mean height (+-500 m), or None for the model's
    own range (RPC); seeds: PAIR_DTYPE records of already matched points (e.g. seeds_from_points);
    automatic: also seek automatic seeds in every tile (default: only when no seeds are given),
    so that tiles without a given seed still grow; a tile tries all its seeds in decreasing rho;
    workers: threads over tiles, or an execution.Execution (results identical). Returns the
    accepted lattice points as a PAIR_DTYPE array sorted by (y1, x1); `seed` holds the id of the
    seed each point grew from (index into `seeds`, or len(seeds) + tile * seed_stride(params) + k
    for automatic ones). Raises InputError for images smaller than the template or without overlap, CancelledError
    when cancelled; no accepted seed gives an empty array and a message via feedback."""
    image1, image2, model1, model2 = pair
    job, tiles = grow_job(ImagePair(image1, image2, model1, model2), params, height_range, seeds, automatic)
    fb = ensure(feedback)
    progress_step(feedback, 0.0)
    where = workers if isinstance(workers, Execution) else Execution("threads", max(int(workers), 1))
    parts = run_tasks(_grow_tile, [(job, i, box) for i, box in enumerate(tiles)], where, feedback, "region growing")
    records = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, PAIR_DTYPE)
    records = records[np.lexsort((records["x1"], records["y1"]))]
    tries = sum(p[1] for p in parts)
    nseeds = sum(p[2] for p in parts)
    if len(records) == 0:
        fb.pushInfo(
            "Warning: region growing found no matched point: no seed passed the acceptance criteria "
            f"({nseeds} seed(s) in {len(tiles)} tile(s)); check the image pair, the height range and "
            "the texture, or give seeds"
        )
    else:
        fb.pushInfo(
            f"region growing: {len(records)} points accepted of {tries} LSM attempts from {nseeds} seed(s) "
            f"in {len(tiles)} tile(s)"
        )
    return records


def transfer_points(pair: ImagePair, x1, y1, params=None, height_range=None, guide=None, x2=None, y2=None):
    """LSM of GIVEN image-1 points into image 2 (only image-2 coordinates are matched; transfer
    points of the three-image combinations), on the resolution-adapted images. Initial values: from
    `guide` (PAIR_DTYPE points of this pair already matched: the nearest one's position and affine
    transported to the point), else from approximate image-2 positions x2, y2 or the sensor models
    (NCC near them or along the predicted path over the height range, then LSM, as
    seeds_from_points). Returns (PAIR_DTYPE records in the order of x1, ok mask of the
    accepted ones)."""
    image1, image2, model1, model2 = pair
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    x1 = np.atleast_1d(np.asarray(x1, float)).ravel()
    y1 = np.atleast_1d(np.asarray(y1, float)).ravel()
    if x1.shape != y1.shape:
        raise InputError("x1 and y1 must have the same length")
    hr = HeightRange.resolve(height_range, model1).bounds
    image1, image2 = adapt_resolution(image1, image2, model1, model2, params, hr)
    if guide is None or len(guide) == 0:
        return seeds_from_points(ImagePair(image1, image2, model1, model2), x1, y1, params, hr, x2=x2, y2=y2)
    guide = _as_seed_records(guide)
    if len(guide) == 0:
        raise InputError("the guide points have no matched image-2 positions")
    from scipy.spatial import cKDTree

    _, nearest = cKDTree(np.column_stack([guide["x1"], guide["y1"]])).query(np.column_stack([x1, y1]))
    g = guide[nearest]
    a = np.column_stack([g[k].astype(float) for k in ("a1", "a2", "a4", "a5")])
    dk, dl = x1 - g["x1"], y1 - g["y1"]
    x2 = g["x2"] + a[:, 0] * dk + a[:, 1] * dl
    y2 = g["y2"] + a[:, 2] * dk + a[:, 3] * dl
    records, ok = match_windows(image1, image2, x1, y1, x2, y2, a, params)
    records["seed"] = nearest
    return records, ok


def match_windows(image1, image2, x1, y1, x2, y2, a, params):
    """LSM (lsm.match_accepted with GrowParams `params`) of image-1 points (x1, y1) from the image-2
    positions (x2, y2) and initial affines `a` (n, 4: a1, a2, a4, a5), on windows of the Images `image1`,
    `image2` read per params.tile px of image 1. Returns (PAIR_DTYPE records in the order of x1, NaN where
    none was tried, seed -1; ok mask of the accepted ones)."""
    records = np.zeros(len(x1), PAIR_DTYPE)
    records["x1"], records["y1"] = x1, y1
    for name in PAIR_DTYPE.names[2:-1]:
        records[name] = np.nan if PAIR_DTYPE[name].kind == "f" else 0
    records["seed"] = -1
    ok = np.zeros(len(x1), bool)
    half = params.widest // 2
    tile = int(params.tile)
    key = np.floor(y1 / tile) * (image1.size[0] // tile + 1) + np.floor(x1 / tile)
    for k in np.unique(key[np.isfinite(key)]):
        idx = np.flatnonzero(key == k)
        pad = half + 3
        xa, ya = int(np.floor(x1[idx].min())) - pad, int(np.floor(y1[idx].min())) - pad
        win1, ox1, oy1 = image1.read(
            xa, ya, int(np.ceil(x1[idx].max())) + pad + 1 - xa, int(np.ceil(y1[idx].max())) + pad + 1 - ya
        )
        scale = np.nanmax(np.abs(a[idx])) if np.isfinite(a[idx]).any() else 1.0
        m = (half + 3) * scale + params.max_shift + 3
        fin = np.isfinite(x2[idx]) & np.isfinite(y2[idx])
        if not fin.any() or win1.shape[0] < 4 or win1.shape[1] < 4:
            continue
        xb, yb = int(np.floor(x2[idx][fin].min() - m)), int(np.floor(y2[idx][fin].min() - m))
        win2, ox2, oy2 = image2.read(
            xb, yb, int(np.ceil(x2[idx][fin].max() + m)) + 1 - xb, int(np.ceil(y2[idx][fin].max() + m)) + 1 - yb
        )
        if win2.shape[0] < 4 or win2.shape[1] < 4:
            continue
        rec, good = match_accepted(
            win1, win2, x1[idx] - ox1, y1[idx] - oy1, x2[idx] - ox2, y2[idx] - oy2, affine=a[idx], params=params
        )
        rec["x1"] += ox1
        rec["y1"] += oy1
        rec["x2"] += ox2
        rec["y2"] += oy2
        records[idx] = rec
        ok[idx] = good
    return records, ok
