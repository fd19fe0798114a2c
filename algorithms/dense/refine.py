"""Sub-pixel refinement of dense image-2 positions by least-squares matching in the original images.

Each dense point (x1, y1) -> (x2, y2) is matched again by LSM (matching.lsm through
region_growing.match_windows: an affine template of GrowParams.template px on the resolution-adapted
images, with LSM's robust weighting where `robust`: Tukey's biweight keeps the samples of a forest or a
building beside a field from pulling the field's match), starting at its dense position with the models'
local affine at the middle height (per AFFINE_CELL). The LSM result replaces the dense position where it
passes region growing's acceptance criteria (rho, error ellipse, iterations) and lies within `max_shift` px
of the dense position: a larger move means a template that straddles two surfaces (a forest edge, a building) or
a semi-global mismatch, where LSM found another surface than the census window's. Moves up to about 1 px are
mostly LSM correcting the semi-global position on open ground (its sub-pixel fit, the epipolar resampling;
studies/README.md#dense_variance_test measures the bound). A refined point carries LSM's rho and error-ellipse
semi-axes (its precision); the others keep NaN; those the bias test below sends back to their semi-global positions
keep LSM's rho with the semi-global precision's axes.

A wider second window (DenseParams.wide_template; lsm.match_accepted's, with GrowParams.wide_beyond_shift off): a
node the template fails at without moving beyond the largest shift (too low a rho, too wide an ellipse, singular or
not converged) is matched again from its dense position with the wide window, under the same criteria and the same
largest shift. A node the template moved too
far is not tried again: its template straddles a height step, which a wider one straddles more. A weak texture
(crops, grass) gives a small template too little signal to converge or to pass rho and the error ellipse; the
wide window has about (wide / template)^2 times the signal. The shift bound keeps it on the dense position's
surface. Measured in studies/README.md#dense_wide.

Masked pixels (matching.imagery: nodata, saturated): a node whose LSM window touches one, in image 1 at the
node or in image 2 at its dense position, yields no point at all (its position becomes NaN), refined or not:
a template with a masked sample cannot be matched, and the dense position beside a nodata edge or a saturated
patch is the least trustworthy one. The window: the template's samples with their interpolation and gradient
support (TEMPLATE_SUPPORT px beyond the template's half width), in image 2 through the models' local affine
and widened by `max_shift`, on the resolution-adapted images LSM reads (whose low-pass spreads a masked pixel
over its support).

Isolated refinements (`isolated`, on a lattice): the templates of neighbouring nodes overlap almost entirely,
so where the surface lets LSM succeed it succeeds at most of them. A node LSM accepted while fewer than
LEAST_REFINED of the (2 REACH + 1)^2 - 1 nodes around it were accepted is more likely a chance fit to a
mismatch (repetitive or weak texture: the semi-global position it started from was already wrong) than a
lone good match; it keeps its dense position. Where the DEM takes refined points only, one such point
otherwise sets the heights of the empty cells around it. The test runs per tile: a node at a tile's edge has
fewer nodes around it (a corner 8), so there it is a little stricter.

The bias test (`biased`, on a lattice, after the isolation test; both in `lattice_tests`): where the template sees
one surface that LSM's affine fits, LSM's move from the semi-global position is the semi-global matcher's error,
which changes sign from node to node (its sub-pixel fit's pixel locking, the census window's noise), so LSM's moves
average out over the nodes around. Where the template straddles heights it cannot fit (a building and the street
beside it), LSM pulls every template that overlaps them towards their mixture, the same way: its moves agree over
the neighbourhood, and the semi-global position, whose census window follows the height step, is the better one.
With t the refined nodes' moves along the epipolar line (px of image 2, EpipolarGrid.along) within a square of
BIAS_WINDOW templates around a node (at least BIAS_NODES of them), the node keeps its semi-global position where
    |mean(t)| > max(b sd(t), k (w_t / w_c) a)
b = DenseParams.bias_bound; a the node's LSM error-ellipse semi-major axis (in the template's units,
lsm.match_accepted) and w_t / w_c the template's width over the census window's: the census sees (w_t / w_c)^2
fewer samples than the template, so k (w_t / w_c) a predicts the semi-global position's own error (k =
DenseParams.census_error: the sub-pixel fit's pixel locking adds to the census's noise), which the move must exceed
to be LSM's bias and not a correction of a weak census match (crops, low texture). The test reads positions and
LSM's ellipse, not the images' radiometry or a noise model (a residual test did, and failed on real images:
studies/README.md#dense_variance_test). The straddling template is the reference image's, which a triplet's two
pairs share: where the test finds one pair's moves systematic, both pairs' refined positions of the node keep their
semi-global ones (the caller's, dense/dense_strategy.py). Such a position is measured (its rho is LSM's at the
node: the template correlates there) with the semi-global matcher's precision (dense/precision.py,
SEMI_GLOBAL_AXIS). Measured in studies/README.md#dense_bias_test.

Measured on the simulated triplet (docs/validation.md#dense-matching, with the plain LSM): LSM halves the dense
position's error on open ground where it is accepted, and makes it worse within a template of a height step;
the robust weights and the isolation test: docs/validation.md#dense-robust-lsm."""

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from ..height_range import HeightRange
from ..matching.imagery import as_image, touches_masked
from ..matching.pair_geometry import ImagePair, local_affine
from ..matching.params import GrowParams
from ..matching.region_growing import match_windows
from ..matching.resolution import adapt_resolution
from .epipolar import EpipolarGrid
from .params import DenseParams

#: px of image 1: the cells of LSM's initial affine (the models' local affine: only LSM's starting shape, which
#: LSM estimates; how little it changes across a cell: tests/algorithms/dense/test_dense_strategy.py)
AFFINE_CELL = 32
#: lattice nodes (Chebyshev) around a refined node, and the fewest of them refined too (module docstring)
REACH, LEAST_REFINED = 2, 3
#: the bias test (module docstring): its window (templates) and the fewest refined nodes in it
BIAS_WINDOW, BIAS_NODES = 1.5, 9
#: px beyond LSM's template that its samples read: bicubic resampling in image 2 (2), bilinear samples and their
#: central-difference gradients in image 1 (1 + 1)
TEMPLATE_SUPPORT = 2


class Refined(NamedTuple):
    """refine_positions' result per point: image-2 positions (px; NaN: no point), and LSM's rho and error-ellipse
    semi-axes (px) where LSM refined the position (NaN elsewhere)."""

    x2: np.ndarray
    y2: np.ndarray
    rho: np.ndarray
    semi_major: np.ndarray
    semi_minor: np.ndarray


class Conjugates(NamedTuple):
    """Points (x1, y1) of image 1 and their positions (x2, y2) in image 2 (px; NaN: unmatched)."""

    x1: np.ndarray
    y1: np.ndarray
    x2: np.ndarray
    y2: np.ndarray


def refine_positions(
    pair: ImagePair,
    points: Conjugates,
    height_range: tuple,
    params: GrowParams,
) -> Refined:
    """The refined image-2 positions of points (x1, y1) matched at (x2, y2) (NaN: unmatched, left as they are; and
    NaN where LSM's window touches a masked pixel: no point), with LSM's quality (module docstring): LSM with the
    GrowParams `params` (DenseParams.refinement: template, acceptance criteria, largest shift, robust weights, the
    wide window). Images given as paths or arrays mask their saturated pixels too. The isolation test (`isolated`)
    is the caller's, on its lattice."""
    x1, y1, x2, y2 = points
    image1, image2, model1, model2 = pair
    x2, y2 = np.array(x2, float), np.array(y2, float)
    rho, major, minor = (np.full(x2.size, np.nan, np.float32) for _ in range(3))
    idx = np.flatnonzero(np.isfinite(x2) & np.isfinite(y2))
    if idx.size == 0:
        return Refined(x2, y2, rho, major, minor)
    h_m = 0.5 * (height_range[0] + height_range[1])
    # LSM's initial affine: the models' local affine at the middle height, once per AFFINE_CELL px cell
    cells = np.column_stack([np.floor(v[idx] / AFFINE_CELL) for v in (x1, y1)])
    cells, cell = np.unique(cells, axis=0, return_inverse=True)
    cx, cy = (np.clip((c + 0.5) * AFFINE_CELL, v[idx].min(), v[idx].max()) for c, v in zip(cells.T, (x1, y1)))
    affine = np.column_stack(local_affine(model1, model2, cx, cy, h_m)[2:])[cell.ravel()]
    params = params.check()
    image1, image2 = adapt_resolution(
        as_image(image1, saturation=True),
        as_image(image2, saturation=True),
        model1,
        model2,
        params,
        HeightRange.resolve(height_range, model1).bounds,
    )
    half = params.template // 2
    reach = half * np.abs(affine).reshape(-1, 2, 2).sum(axis=2) + TEMPLATE_SUPPORT + params.max_shift
    masked = touches_masked(
        image1, x1[idx], y1[idx], half + TEMPLATE_SUPPORT, half + TEMPLATE_SUPPORT
    ) | touches_masked(image2, x2[idx], y2[idx], reach[:, 0], reach[:, 1])
    x2[idx[masked]], y2[idx[masked]] = np.nan, np.nan
    idx, affine = idx[~masked], affine[~masked]
    records, accepted = match_windows(image1, image2, x1[idx], y1[idx], x2[idx], y2[idx], affine, params)
    take = idx[accepted]
    r = records[accepted]
    x2[take], y2[take] = r["x2"], r["y2"]
    rho[take], major[take], minor[take] = r["rho"], r["semi_major"], r["semi_minor"]
    return Refined(x2, y2, rho, major, minor)


def lattice_tests(
    points: Conjugates, refined: Refined, grid: EpipolarGrid, params: DenseParams
) -> tuple[Refined, np.ndarray]:
    """The tests on the lattice of `points` (DenseParams.step px apart) after LSM (module docstring): `refined` with
    its isolated refinements back at their dense positions (their quality NaN), and the bias test's mask of the
    nodes whose positions go back to the semi-global ones (the caller applies it, to every pair of a triplet);
    `grid` the tile's epipolar grid."""
    x1, y1, x2, y2 = points
    lone = isolated(x1, y1, np.isfinite(refined.rho), params.step)
    rx, ry = np.where(lone, x2, refined.x2), np.where(lone, y2, refined.y2)
    rho, major, minor = (np.where(lone, np.float32(np.nan), v) for v in refined[2:])
    moves = np.where(np.isfinite(rho), grid.along(rx - x2, ry - y2), np.nan)
    return Refined(rx, ry, rho, major, minor), biased(x1, y1, moves, major, params)


def window_sums(
    x1: np.ndarray, y1: np.ndarray, step: int, where: np.ndarray, values: list[np.ndarray], size: int
) -> list[np.ndarray]:
    """Per lattice node (x1, y1) (`step` px apart), the sum of each of `values` (given at the nodes `where`; the
    other nodes count 0) over the size x size nodes around it, truncated at the lattice's edges."""
    j = np.rint((x1 - x1.min()) / step).astype(np.int64)
    i = np.rint((y1 - y1.min()) / step).astype(np.int64)
    shape = (int(i.max()) + 1, int(j.max()) + 1)
    sums = []
    for value in values:
        grid = np.zeros(shape)
        grid[i[where], j[where]] = value
        sums.append(ndimage.uniform_filter(grid, size, mode="constant")[i, j] * size * size)
    return sums


def isolated(x1: np.ndarray, y1: np.ndarray, refined: ArrayLike, step: int) -> np.ndarray:
    """Mask of the `refined` nodes among lattice nodes (x1, y1) `step` px apart with fewer than LEAST_REFINED
    refined nodes within REACH nodes (module docstring; nodes beyond the given ones count as unrefined)."""
    refined = np.asarray(refined, bool)
    if not refined.any():
        return refined.copy()
    (count,) = window_sums(x1, y1, step, refined, [np.ones(int(refined.sum()))], 2 * REACH + 1)
    return refined & (np.rint(count) - 1 < LEAST_REFINED)


def biased(x1: np.ndarray, y1: np.ndarray, moves: np.ndarray, axes: np.ndarray, params: DenseParams) -> np.ndarray:
    """Mask of the lattice nodes (x1, y1) DenseParams.step px apart whose refined neighbours' `moves` (px of image 2
    along the epipolar line, NaN where not refined) are systematic (module docstring: the bias test, with LSM's
    error-ellipse semi-major `axes` at the nodes); only refined nodes are marked. The window is truncated at the
    lattice's edges."""
    refined = np.isfinite(moves)
    if params.bias_bound <= 0 or refined.sum() < BIAS_NODES:
        return np.zeros(refined.shape, bool)
    size = max(3, int(round(BIAS_WINDOW * params.template / params.step)) | 1)
    values = [np.ones(int(refined.sum())), moves[refined], moves[refined] ** 2]
    n, s1, s2 = window_sums(x1, y1, params.step, refined, values, size)
    census = params.census_error * params.template / (2 * params.sgm.census_radius + 1) * np.asarray(axes, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s1 / n
        sd = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0))
        return refined & (n >= BIAS_NODES - 0.5) & (np.abs(mean) > np.maximum(params.bias_bound * sd, census))
