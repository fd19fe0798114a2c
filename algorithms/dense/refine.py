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
studies/README.md#dense_variance_test measures the bound). The variance test below (off by default) is meant to
find the templates that straddle heights. A refined point carries LSM's rho and error-ellipse semi-axes (its
precision); the others keep NaN.

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

The variance test (VarianceTest): an accepted LSM position is kept only where LSM's affine fits one surface. LSM
leaves the template residual s_t sqrt(1 - rho^2) (s_t the standard deviation of image 1's grey values in the
default template at the node, rho LSM's correlation: the residual's RMS after LSM's radiometric fit); one surface
under an affine leaves the noise, so q = s_t sqrt(1 - rho^2) / sigma_n is about 1 (sigma_n image 1's noise,
matching.image_noise). A template over roofs and streets, or crowns and gaps, whose heights change within it,
leaves more: where q > VarianceTest.bound the node keeps its dense position, which the 5 x 5 census window
measured on the surface at the node. It is still a measured position (its rho is LSM's, its error-ellipse
semi-axes NaN: not LSM's position; `kept` says which). This is Foerstner's test of the variance factor, node by
node. s_t is taken over the default template also where the wide window matched (a weak texture: q is small
there), and on image 1 as given, not on the low-passed image LSM reads (the model of the study that chose it). A
node whose s_t cannot be read (outside the window) has no q and keeps LSM's position. Off by default
(DenseParams.max_residual 0): it needs sigma_n to be the residual of one surface, which holds for white noise
(the simulated scenes) but not for restored and resampled real images, where one surface leaves a residual of
several times Immerkaer's noise and the test would keep nearly every position. Measured in
studies/README.md#dense_variance_test.

Isolated refinements (`isolated`, on a lattice): the templates of neighbouring nodes overlap almost entirely,
so where the surface lets LSM succeed it succeeds at most of them. A node LSM accepted while fewer than
LEAST_REFINED of the (2 REACH + 1)^2 - 1 nodes around it were accepted is more likely a chance fit to a
mismatch (repetitive or weak texture: the semi-global position it started from was already wrong) than a
lone good match; it keeps its dense position. Where the DEM takes refined points only, one such point
otherwise sets the heights of the empty cells around it. The test runs per tile: a node at a tile's edge has
fewer nodes around it (a corner 8), so there it is a little stricter.

Measured on the simulated triplet (docs/validation.md#dense-matching, with the plain LSM): LSM halves the dense
position's error on open ground where it is accepted, and makes it worse within a template of a height step;
the robust weights and the isolation test: docs/validation.md#dense-robust-lsm."""

from typing import NamedTuple

import numpy as np
from scipy import ndimage

from ..height_range import HeightRange
from ..matching.imagery import Image, as_image, touches_masked
from ..matching.pair_geometry import ImagePair, local_affine
from ..matching.params import GrowParams
from ..matching.region_growing import match_windows
from ..matching.resolution import adapt_resolution

#: px of image 1: the cells of LSM's initial affine (the models' local affine: only LSM's starting shape, which
#: LSM estimates; how little it changes across a cell: tests/algorithms/dense/test_dense_strategy.py)
AFFINE_CELL = 32
#: lattice nodes (Chebyshev) around a refined node, and the fewest of them refined too (module docstring)
REACH, LEAST_REFINED = 2, 3
#: px beyond LSM's template that its samples read: bicubic resampling in image 2 (2), bilinear samples and their
#: central-difference gradients in image 1 (1 + 1)
TEMPLATE_SUPPORT = 2


class VarianceTest(NamedTuple):
    """The variance test (module docstring): image 1's noise sigma_n (DN; NaN: no test) and the largest q kept."""

    noise: float
    bound: float


class Refined(NamedTuple):
    """refine_positions' result per point: image-2 positions (px; NaN: no point), LSM's rho and error-ellipse
    semi-axes (px) where LSM measured the point (NaN elsewhere; the semi-axes NaN too where the variance test kept
    the dense position), and `kept`: LSM accepted, the variance test kept the dense position."""

    x2: np.ndarray
    y2: np.ndarray
    rho: np.ndarray
    semi_major: np.ndarray
    semi_minor: np.ndarray
    kept: np.ndarray


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
    test: VarianceTest | None = None,
) -> Refined:
    """The refined image-2 positions of points (x1, y1) matched at (x2, y2) (NaN: unmatched, left as they are; and
    NaN where LSM's window touches a masked pixel: no point), with LSM's quality (module docstring): LSM with the
    GrowParams `params` (DenseParams.refinement: template, acceptance criteria, largest shift, robust weights, the
    wide window), and the variance `test` (None: none). Images given as paths or arrays mask their saturated pixels
    too. The isolation test (`isolated`) is the caller's, on its lattice."""
    x1, y1, x2, y2 = points
    image1, image2, model1, model2 = pair
    x2, y2 = np.array(x2, float), np.array(y2, float)
    rho, major, minor = (np.full(x2.size, np.nan, np.float32) for _ in range(3))
    kept = np.zeros(x2.size, bool)
    idx = np.flatnonzero(np.isfinite(x2) & np.isfinite(y2))
    if idx.size == 0:
        return Refined(x2, y2, rho, major, minor, kept)
    h_m = 0.5 * (height_range[0] + height_range[1])
    # LSM's initial affine: the models' local affine at the middle height, once per AFFINE_CELL px cell
    cells = np.column_stack([np.floor(v[idx] / AFFINE_CELL) for v in (x1, y1)])
    cells, cell = np.unique(cells, axis=0, return_inverse=True)
    cx, cy = (np.clip((c + 0.5) * AFFINE_CELL, v[idx].min(), v[idx].max()) for c, v in zip(cells.T, (x1, y1)))
    affine = np.column_stack(local_affine(model1, model2, cx, cy, h_m)[2:])[cell.ravel()]
    params = params.check()
    original = as_image(image1, saturation=True)
    image1, image2 = adapt_resolution(
        original,
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
    rho[take] = r["rho"]
    moved = np.ones(take.size, bool)
    if test is not None and np.isfinite(test.noise) and test.noise > 0:
        q = residual_ratio(original, x1[take], y1[take], r["rho"], params.template, test.noise)
        moved = ~(q > test.bound)
        kept[take[~moved]] = True
    take, r = take[moved], r[moved]
    x2[take], y2[take] = r["x2"], r["y2"]
    major[take], minor[take] = r["semi_major"], r["semi_minor"]
    return Refined(x2, y2, rho, major, minor, kept)


def residual_ratio(
    image: Image, x: np.ndarray, y: np.ndarray, rho: np.ndarray, template: int, noise: float
) -> np.ndarray:
    """q = s_t sqrt(1 - rho^2) / noise at image points (x, y) (module docstring): s_t the standard deviation of the
    Image-like `image`'s grey values in the `template` px square around each point's pixel."""
    q = np.full(np.shape(x), np.nan)
    if q.size == 0:
        return q
    half = template // 2
    j, i = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    data, ox, oy = image.read(
        int(j.min()) - half, int(i.min()) - half, int(np.ptp(j)) + template, int(np.ptp(i)) + template
    )
    if data.size == 0:
        return q
    mean = ndimage.uniform_filter(data.astype(float), template, mode="nearest")
    square = ndimage.uniform_filter(np.square(data, dtype=float), template, mode="nearest")
    std = np.sqrt(np.maximum(square - mean * mean, 0.0))
    rows, cols = data.shape
    a, b = j - ox, i - oy
    inside = (a >= 0) & (b >= 0) & (a < cols) & (b < rows)
    s_t = np.where(inside, std[np.clip(b, 0, rows - 1), np.clip(a, 0, cols - 1)], np.nan)
    return s_t * np.sqrt(np.maximum(1.0 - np.square(np.asarray(rho, float)), 0.0)) / float(noise)


def isolated(x1, y1, refined, step):
    """Mask of the `refined` nodes among lattice nodes (x1, y1) `step` px apart with fewer than LEAST_REFINED
    refined nodes within REACH nodes (module docstring; nodes beyond the given ones count as unrefined)."""
    refined = np.asarray(refined, bool)
    if not refined.any():
        return refined.copy()
    j = np.rint((x1 - x1.min()) / step).astype(np.int64)
    i = np.rint((y1 - y1.min()) / step).astype(np.int64)
    grid = np.zeros((i.max() + 1, j.max() + 1), np.float32)
    grid[i[refined], j[refined]] = 1.0
    size = 2 * REACH + 1
    around = np.rint(ndimage.uniform_filter(grid, size, mode="constant") * size * size) - grid
    return refined & (around[i, j] < LEAST_REFINED)
