"""Affine image-space bias of search images against a reference image, from the rays of matched points
(the orientation that the MPGC refinement's geometric constraint rests on, refinement.py).

The supplied models are biased (tens of metres before the adjustment), and their relative errors
vary across a scene. Each search image gets an affine image-space bias,
    x_ip = M_i f_i(X_p) + d_i + (x_0p - f_0(X_p)),
f_i the model's projection, X_p the least-squares intersection of the points' bias-corrected
positions, fitted by least squares with the residuals beyond 3 robust sigmas left out and iterated
`BIAS_ITERATIONS` times. The reference image's residual is moved to the search images (the last
term), so the common along-track part, which the rays cannot see, does not drift. An affine map,
not a constant shift, because the relative errors vary across the scene
(docs/validation.md#orientation-bias). The corrected models are
coarse_to_fine_level.ShiftedModels; `systematic`, the RMS of the residuals' medians in tiles of the
points' extent in the reference image (the worst image coordinate), measures the orientation's
consistency after the correction (refinement.py weights MPGC's geometric observations by it, so that
an orientation the affine maps do not fit loosens the constraint instead of biasing the matches)."""

import numpy as np

from ..surface.intersection import intersect_measured
from .coarse_to_fine_level import ShiftedModel

BIAS_ITERATIONS = 4
#: median of the length of a 2-D normal vector of unit sigma per axis, sqrt(2 ln 2)
RAYLEIGH_MEDIAN = 1.1774
#: the points' extent in the reference image is cut into GRID x GRID tiles whose residual medians
#: measure the orientation's consistency (tiles with at least TILE_POINTS points)
CONSISTENCY_GRID = 4
TILE_POINTS = 20


def _fit_affine(target, f, centre):
    """(linear 2 x 2, shift 2) of target ~ M f + d by least squares in coordinates centred at
    `centre`, refitted once without the points beyond 3 robust sigmas."""
    ok = np.isfinite(target).all(axis=0) & np.isfinite(f).all(axis=0)
    design = np.column_stack([np.ones(f.shape[1]), f[0] - centre[0], f[1] - centre[1]])
    coef = np.zeros((2, 3))
    for _ in range(2):
        for c in range(2):
            coef[c] = np.linalg.lstsq(design[ok], target[c, ok] - f[c, ok], rcond=None)[0]
        misfit = np.hypot(*(target - f - coef @ design.T))
        ok &= misfit <= max(3.0 * np.median(misfit[ok]) / RAYLEIGH_MEDIAN, 1e-9)
    linear = np.eye(2) + coef[:, 1:]
    return linear, coef[:, 0] - coef[:, 1:] @ centre


def affine_bias(models, cols, rows, iterations=BIAS_ITERATIONS):
    """(corrected models: the reference and ShiftedModels of the search images, Intersection of
    the corrected positions, systematic px) for positions cols, rows (k, m) of m points in the k
    images of `models` (reference first); module docstring. `systematic`: the RMS over
    CONSISTENCY_GRID x CONSISTENCY_GRID tiles of the points' extent in the reference image (tiles
    with >= TILE_POINTS points; NaN where there is none) of the ray residuals' medians, in the
    image coordinate where it is largest."""
    k = len(models)
    maps = [(np.eye(2), np.zeros(2)) for _ in range(k)]
    for _ in range(iterations):
        inter = intersect_measured(models, *_unbiased(maps, cols, rows))
        f = np.array([np.array(m.ground_to_image(inter.lon, inter.lat, inter.h), float) for m in models])
        r0 = np.array([cols[0], rows[0]]) - f[0]
        for i in range(1, k):
            maps[i] = _fit_affine(np.array([cols[i], rows[i]]) - r0, f[i], 0.5 * np.array(models[i].size, float))
    inter = intersect_measured(models, *_unbiased(maps, cols, rows))
    corrected = [models[0]] + [ShiftedModel(m, *maps[i][1], linear=maps[i][0]) for i, m in enumerate(models) if i]
    residuals = np.concatenate(
        [
            np.array([cols[i], rows[i]]) - np.array(corrected[i].ground_to_image(inter.lon, inter.lat, inter.h), float)
            for i in range(k)
        ]
    )
    key = _tile(cols[0]) * CONSISTENCY_GRID + _tile(rows[0])
    medians = [np.nanmedian(residuals[:, key == t], axis=1) for t in np.unique(key) if np.sum(key == t) >= TILE_POINTS]
    if not medians:
        return corrected, inter, float("nan")
    # the worst image coordinate: RMS over the tiles of its residual medians
    return corrected, inter, float(np.nanmax(np.sqrt(np.nanmean(np.square(medians), axis=0))))


def _tile(v):
    """Index 0 .. CONSISTENCY_GRID - 1 of v's tile across the extent of v."""
    lo, hi = np.nanmin(v), np.nanmax(v)
    return np.clip(np.floor((v - lo) / max(hi - lo, 1e-9) * CONSISTENCY_GRID), 0, CONSISTENCY_GRID - 1)


def _unbiased(maps, cols, rows):
    """The positions mapped back through the affine maps, M^-1 (x - d)."""
    out = np.empty((2,) + cols.shape)
    for i, (linear, shift) in enumerate(maps):
        out[:, i] = np.linalg.solve(linear, np.array([cols[i], rows[i]]) - shift[:, None])
    return out[0], out[1]


def intersect_corrected(models, corrected, cols, rows):
    """The Intersection of positions cols, rows (k, m) with the biases of `corrected` (affine_bias's
    corrected models of `models`) taken out, as affine_bias intersects its own points."""
    maps = [(np.eye(2), np.zeros(2))] + [
        (np.asarray(c.linear, float), np.array([c.dx, c.dy], float)) for c in corrected[1:]
    ]
    return intersect_measured(models, *_unbiased(maps, cols, rows))
