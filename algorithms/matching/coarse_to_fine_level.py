"""One pyramid level of the coarse-to-fine matcher (Zhang & Gruen; orchestration in
coarse_to_fine.py): primitives, level geometry, the window choice per point, the candidates of
geometrically constrained cross-correlation along the quasi-epipolar path, their resolution, the
orientation bias, edge points and the TIN that guides the next level.

Per level, primitives of the reference: Foerstner points (one per `patch` x `patch` cell) and grid
points (`grid` px apart at level 0, `coarse_grid` above), each searched in every search image over a
height interval: the block's range at the top, below it the previous level's TIN height +- (`tol_px`
px of parallax + the TIN roughness there). Up to `max_candidates` candidates per image are resolved
by the third image (height agreement), the peak ratio and relaxation (relaxation.py, not across the
Canny edges of the reference level with `edges`), then back-matched in every search image (a failing
image drops out of the point). Each search image's orientation bias (a constant image shift) comes
from the unique candidates (estimate_shift). With `edge_points`, linked edge chains are matched
edgel by edgel with figural continuity (edges.match_edges); edgels ok in every search image whose
heights agree within agree_px of parallax are extra points (flag EDGE).

Level geometry: level L of the factor-f pyramid has pixels of s = f^L full-resolution pixels whose
edges align (level position (x, y) is full position (s x, s y)); `LevelModel` wraps a sensor model.

Window choice (Kanade & Okutomi 1994, by the expected error instead of their full adaptive
search; Zhang & Gruen, section 3.2): a w x w window has the expected shift error
    e^2 = sigma_n^2 2 / sum g^2  +  a mean|xi|
(sigma_n the image noise, g the grey-level gradients in the window; the second term is K-O's
disparity departing from the centre's with variance a |xi| at distance xi, taken as systematic),
a = rough_px^2 / spacing from the previous level's TIN roughness in px of parallax less (in
quadrature) its median, the matching noise. Each point takes the smallest size whose e reaches
`target` px, else the one with the smallest e. The NCC threshold drops likewise with the roughness
(rho_thresholds).

Candidates: the reference ray of a point is cut by the height interval [h_lo, h_hi]; its
projection into the search image (quasi-epipolar path) is sampled every <= PATH_STEP px (each
point at its own spacing, the counts rounded up to multiples of COUNT_BUCKET), widened by
`across` px on each side for orientation errors, and the template (shaped by the models' local
affine) is correlated at every sample (ncc.ncc_path), all points in one numba kernel
(coarse_to_fine_kernels.path_candidates). Local maxima along the path of the
across-maximum profile above rho_min are candidates (at most `max_candidates`, best first),
refined by a parabola in height and across the path; each carries its height, rho and image
position. `second` is the best local maximum besides the first (for the peak ratio)."""

import math
from typing import Any, NamedTuple

import numpy as np
from scipy import ndimage

from ..stats import NMAD_SCALE
from ..surface.tin import conform_breaklines, delaunay, filter_blunders, neighbour_residuals
from ..surface.tin_grid import Grid, rasterize
from .coarse_to_fine_kernels import Affines, Found, Paths, path_candidates
from .edges import EdgeMatching, match_edges
from .interest import interest_points
from .pair_geometry import ImagePair, local_affine, predict
from .relaxation import hypotheses, relax, unique_choice

#: pyramid reduction factor between levels
FACTOR = 3

#: largest spacing (px) of the samples along a path
PATH_STEP = 0.5
#: sample counts are rounded up to a multiple of this, so the points run in a few equal-count batches
COUNT_BUCKET = 8


class ShiftedModel:
    """A sensor model whose image positions are moved by (dx, dy) full px, (col', row') = M (col,
    row) + (dx, dy) with M = `linear` (default the identity): the bias compensation of an
    orientation error (estimate_shift's shifts, orientation_bias.affine_bias's
    affine maps), or the model of a window of the image (dx, dy = minus its top-left corner,
    `size` its size: the tiles of coarse_to_fine.py)."""

    def __init__(self, model, dx=0.0, dy=0.0, size=None, linear=None):
        self.model, self.dx, self.dy = model, float(dx), float(dy)
        self.size = model.size if size is None else tuple(size)
        self.linear = np.eye(2) if linear is None else np.asarray(linear, float).reshape(2, 2)
        self._inverse = np.linalg.inv(self.linear)

    def _unmoved(self, col, row):
        u = np.asarray(col, float) - self.dx
        v = np.asarray(row, float) - self.dy
        (a, b), (c, d) = self._inverse
        return a * u + b * v, c * u + d * v

    def image_to_ground(self, col, row, h):
        return self.model.image_to_ground(*self._unmoved(col, row), h)

    def ray_points(self, col, row, h, half):
        return self.model.ray_points(*self._unmoved(col, row), h, half)

    def _moved(self, x, y):
        (a, b), (c, d) = self.linear
        return a * x + b * y + self.dx, c * x + d * y + self.dy

    def ground_to_image(self, lon, lat, h):
        x, y = self.model.ground_to_image(lon, lat, h)
        return self._moved(np.asarray(x, float), np.asarray(y, float))

    def partials(self, lon, lat, h):
        part = dict(self.model.partials(lon, lat, h))
        part["col"], part["row"] = self._moved(np.asarray(part["col"], float), np.asarray(part["row"], float))
        for key in [k for k in part if k.startswith("d_")]:  # d(col, row)/d(...): (..., 2, k), times M
            part[key] = np.einsum("ij,...jk->...ik", self.linear, np.asarray(part[key], float))
        return part


class LevelModel:
    """A sensor model at pyramid scale s (level px = full px / s); `model` is the full one."""

    def __init__(self, model, scale):
        self.model = model
        self.scale = float(scale)
        cols, rows = model.size
        self.size = (int(math.ceil(cols / self.scale)), int(math.ceil(rows / self.scale)))

    def image_to_ground(self, col, row, h):
        s = self.scale
        return self.model.image_to_ground(np.asarray(col, float) * s, np.asarray(row, float) * s, h)

    def ground_to_image(self, lon, lat, h):
        x, y = self.model.ground_to_image(lon, lat, h)
        return np.asarray(x, float) / self.scale, np.asarray(y, float) / self.scale


def noise_sigma(img):
    """Robust image noise (DN): NMAD_SCALE (1.4826) median |Laplacian| / sqrt(20) (the 4-neighbour Laplacian
    multiplies white noise by sqrt(20)), at least 0.3 DN (quantisation)."""
    a = np.asarray(img, float)
    lap = 4 * a[1:-1, 1:-1] - a[:-2, 1:-1] - a[2:, 1:-1] - a[1:-1, :-2] - a[1:-1, 2:]
    lap = lap[np.isfinite(lap)]
    return max(NMAD_SCALE * float(np.median(np.abs(lap))) / math.sqrt(20.0), 0.3) if lap.size else 1.0


def window_halves(img, x, y, sizes, noise, target, rate=None):
    """Half window per point (module docstring): the smallest of `sizes` (odd, px) whose expected
    error sqrt(noise^2 2 / sum g^2 + rate mean|xi|) <= target px, else the one with the smallest
    error. rate: (n,) disparity variance per px of distance (px^2 / px; None: 0, flat)."""
    a = np.nan_to_num(np.asarray(img, float))
    g = np.zeros_like(a)
    g[:, 1:-1] += (0.5 * (a[:, 2:] - a[:, :-2])) ** 2
    g[1:-1] += (0.5 * (a[2:] - a[:-2])) ** 2
    c = np.pad(np.cumsum(np.cumsum(g, 0), 1), ((1, 0), (1, 0)))
    rows, cols = a.shape
    i = np.clip(np.floor(y).astype(np.int64), 0, rows - 1)
    j = np.clip(np.floor(x).astype(np.int64), 0, cols - 1)
    rate = np.zeros(len(x)) if rate is None else np.asarray(rate, float)
    sizes = sorted(int(s) for s in sizes)
    half = np.full(len(x), sizes[-1] // 2, np.int64)
    best = np.full(len(x), np.inf)
    done = np.zeros(len(x), bool)
    for w in sizes:
        h = w // 2
        i0, i1 = np.clip(i - h, 0, rows), np.clip(i + h + 1, 0, rows)
        j0, j1 = np.clip(j - h, 0, cols), np.clip(j + h + 1, 0, cols)
        energy = c[i1, j1] - c[i0, j1] - c[i1, j0] + c[i0, j0]
        k = np.arange(-h, h + 1.0)
        spread = np.hypot(k[:, None], k[None, :]).mean()  # mean |xi|
        with np.errstate(divide="ignore"):
            error = np.sqrt(noise**2 * 2.0 / energy + rate * spread)
        take = ~done & ((error <= target) | (error <= best))
        half[take] = h
        best = np.where(take, error, best)
        done |= error <= target
    return half


def rho_thresholds(rho_min, drop, rough_px):
    """NCC threshold per point (module docstring): rho_min lowered by up to `drop` as the TIN
    roughness reaches 1 px of parallax, rho_min - drop min(1, rough_px)."""
    return rho_min - drop * np.minimum(np.asarray(rough_px, float), 1.0)


def path_samples(model1, model2, x, y, h_lo, h_hi, across, count):
    """Heights (n, count) along each point's ray, evenly from h_lo to h_hi, and their search-image
    positions (n, count, a) with `across` px on each side of the path. Returns (heights, cx, cy,
    offsets)."""
    n = len(x)
    xa, ya = predict(model1, model2, x, y, h_lo)
    xb, yb = predict(model1, model2, x, y, h_hi)
    length = np.hypot(xb - xa, yb - ya)
    t = np.linspace(0.0, 1.0, count)
    heights = h_lo[:, None] + t[None, :] * (h_hi - h_lo)[:, None]
    px, py = predict(model1, model2, np.repeat(x, count), np.repeat(y, count), heights.ravel())
    px, py = px.reshape(n, count), py.reshape(n, count)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(length > 1e-9, (xb - xa) / length, 1.0)
        uy = np.where(length > 1e-9, (yb - ya) / length, 0.0)
    off = np.arange(-across, across + 1, dtype=float)
    cx = px[:, :, None] - uy[:, None, None] * off
    cy = py[:, :, None] + ux[:, None, None] * off
    return heights, cx, cy, off


def sample_counts(model1, model2, x, y, h_lo, h_hi, step=PATH_STEP, bucket=COUNT_BUCKET):
    """Samples per point so that its own path is sampled every <= `step` px (at least 3), rounded up
    to a multiple of `bucket` so that points are searched in a few batches of equal count."""
    xa, ya = predict(model1, model2, x, y, h_lo)
    xb, yb = predict(model1, model2, x, y, h_hi)
    length = np.nan_to_num(np.hypot(xb - xa, yb - ya))
    counts = np.maximum(3, np.ceil(length / step) + 1)
    return (np.ceil(counts / bucket) * bucket).astype(np.int64)


def candidates(pair: ImagePair, x, y, heights: tuple[np.ndarray, np.ndarray], half, across, rho_min, max_candidates):
    """Candidates of points (x, y) of img1 in img2 (module docstring); level models and px. Each
    point's path is sampled at its own spacing (sample_counts), in batches of equal count.
    rho_min: (n,) NCC thresholds.
    Returns dict of (n, C) arrays h, rho, x, y (NaN padded, best first) and (n,) `second`."""
    h_lo, h_hi = heights
    img1, img2, model1, model2 = pair
    n, cmax = len(x), int(max_candidates)
    out = {key: np.full((n, cmax), np.nan) for key in ("h", "rho", "x", "y")}
    out["second"] = np.full(n, np.nan)
    if n == 0:
        return out
    x, y, h_lo, h_hi = (np.asarray(v, float) for v in (x, y, h_lo, h_hi))
    half = np.broadcast_to(np.asarray(half, np.int64), (n,))
    rho_min = np.broadcast_to(np.asarray(rho_min, float), (n,))
    _, _, a1, a2, a4, a5 = local_affine(model1, model2, x, y, 0.5 * (h_lo + h_hi))
    counts = sample_counts(model1, model2, x, y, h_lo, h_hi)
    for count in np.unique(counts):
        sel = np.flatnonzero(counts == count)
        heights, cx, cy, _ = path_samples(model1, model2, x[sel], y[sel], h_lo[sel], h_hi[sel], across, int(count))
        part = {key: np.full((sel.size, cmax), np.nan) for key in ("h", "rho", "x", "y")}
        part["second"] = np.full(sel.size, np.nan)
        vec = [np.ascontiguousarray(v[sel], float) for v in (x, y, a1, a2, a4, a5)]
        paths = Paths(*(np.ascontiguousarray(v) for v in (cx, cy, heights)))
        found = Found(part["h"], part["rho"], part["x"], part["y"])
        path_candidates(
            img1,
            img2,
            vec[0],
            vec[1],
            np.ascontiguousarray(half[sel]),
            paths,
            Affines(*vec[2:]),
            np.ascontiguousarray(rho_min[sel]),
            found,
            part["second"],
        )
        for key, value in part.items():
            out[key][sel] = value
    return out


def back_match(pair: ImagePair, x, y, x2, y2, heights: tuple[np.ndarray, np.ndarray], half, across):
    """Back-matching: the template of img2 at (x2, y2) searched in img1 along its own path over
    the same heights; returns the distance (level px) of the best img1 position from (x, y)
    (inf where nothing correlates)."""
    h_lo, h_hi = heights
    img1, img2, model1, model2 = pair
    back = candidates(
        ImagePair(img2, img1, model2, model1), x2, y2, (h_lo, h_hi), half, across, np.full(len(x2), -1.0), 1
    )
    with np.errstate(invalid="ignore"):
        d = np.hypot(back["x"][:, 0] - x, back["y"][:, 0] - y)
    return np.where(np.isfinite(d), d, np.inf)


def parallax_per_metre(model0, model, x, y, h):
    """Search-image px per metre of height along the reference rays at (x, y) (any level)."""
    return np.hypot(*parallax_vector(model0, model, x, y, h))


class TinGuide:
    """Heights of the accepted points of a level as a TIN (full-resolution reference px) after the
    blunder filter, interpolated (with the roughness |plane residual| of the vertices) on a grid
    of `cell` px for the next level; outside the TIN the nearest grid value. `breaklines`: (n, 3)
    polylines (x, y, h), densified to `spacing` px and conformed (surface/tin.py conform_breaklines:
    no triangle crosses them; their vertices are never filtered, mass points closer than
    spacing / 4 give way)."""

    def __init__(self, x, y, h, shape, cell, k, breaklines=(), spacing=1.0):
        vertices, _, near = conform_breaklines(list(breaklines), x, y, spacing=spacing, min_length=spacing / 2)
        x, y, h = (np.concatenate([v[near], vertices[:, i]]) for i, v in enumerate((x, y, h)))
        fixed = np.arange(len(x)) >= int(near.sum())
        tin = delaunay(x, y)
        keep, self.removed = filter_blunders(tin, x, y, h, k=k, fixed=fixed)
        x, y, h = x[keep], y[keep], h[keep]
        self.count = int(keep.sum())
        tin = delaunay(x, y)
        rough = np.empty(len(h))
        indptr, indices = tin.vertex_neighbor_vertices
        neighbour_residuals(
            indptr, indices, *(np.ascontiguousarray(v, float) for v in (x, y, h)), np.ones(len(h), bool), rough
        )
        rough = np.nan_to_num(np.abs(rough))
        self.cell = float(cell)
        grid = Grid(0.0, 0.0, self.cell, int(math.ceil(shape[1] / cell)) + 1, int(math.ceil(shape[0] / cell)) + 1)
        values = rasterize(x, -y, np.column_stack([h, rough]), tin.simplices, grid)
        missing = ~np.isfinite(values[0])
        if missing.any():
            idx = ndimage.distance_transform_edt(missing, return_distances=False, return_indices=True)
            values = values[:, idx[0], idx[1]]
        self.values = values

    def at(self, x, y):
        """(h, roughness) at full-resolution reference positions."""
        rows, cols = self.values.shape[1:]
        i = np.clip(np.floor(np.asarray(y) / self.cell).astype(np.int64), 0, rows - 1)
        j = np.clip(np.floor(np.asarray(x) / self.cell).astype(np.int64), 0, cols - 1)
        return self.values[0, i, j], self.values[1, i, j]


def estimate_shift(lm, x, y, cands, rho_min, peak_ratio):
    """Orientation bias of each search image (level px), from the points whose best candidate is
    unique (peak ratio) in every search image: median of (matched position - the model's
    prediction at the height of search image 1's match). Image 1's match defines the height, so
    its shift is across its path; image 2's is complete. Also returns the candidates' heights
    corrected for the shifts (h - (d . u) / (px per m), u the path direction). Zero shifts with
    fewer than 10 such points."""
    m = len(cands)
    best = np.ones(len(x), bool)
    for c in cands:
        with np.errstate(invalid="ignore"):
            best &= (c["rho"][:, 0] > rho_min) & ~(c["second"] / c["rho"][:, 0] >= peak_ratio)
    shifts = np.zeros((m, 2))
    heights = [c["h"] for c in cands]
    if best.sum() < 10:
        return shifts, heights
    h1 = cands[0]["h"][best, 0]
    for k, c in enumerate(cands):
        px, py = predict(lm[0], lm[k + 1], x[best], y[best], h1)
        shifts[k] = np.nanmedian(c["x"][best, 0] - px), np.nanmedian(c["y"][best, 0] - py)
        sens = parallax_vector(lm[0], lm[k + 1], x, y, h1.mean())
        along = (shifts[k, 0] * sens[0] + shifts[k, 1] * sens[1]) / (sens[0] ** 2 + sens[1] ** 2)
        heights[k] = c["h"] - along[:, None]
    return shifts, heights


def parallax_vector(model0, model, x, y, h):
    """d(x, y)/dh of the search image along the reference rays at (x, y): px per metre."""
    xa, ya = predict(model0, model, x, y, np.full(len(x), h - 50.0))
    xb, yb = predict(model0, model, x, y, np.full(len(x), h + 50.0))
    return (xb - xa) / 100.0, (yb - ya) / 100.0


def primitives(img, level, params, border):
    """Foerstner points and grid points of a reference level image: (x, y) level px."""
    rows, cols = img.shape
    px, py, _ = interest_points(img, patch=params.patch, window=5, border=border)
    if level == 0:  # region growing's lattice (half template 9): comparable nodes
        gx = np.arange(9.5, cols - border, params.grid)
        gy = np.arange(9.5, rows - border, params.grid)
    else:
        gx = np.arange(border + 0.5, cols - border, params.coarse_grid)
        gy = np.arange(border + 0.5, rows - border, params.coarse_grid)
    gx, gy = (v.ravel() for v in np.meshgrid(gx, gy))
    inside = (gx >= border) & (gy >= border)
    x, y = np.concatenate([px, gx[inside]]), np.concatenate([py, gy[inside]])
    first = np.sort(np.unique(np.column_stack([x, y]), axis=0, return_index=True)[1])  # a Foerstner point on a node
    return x[first], y[first]


class LevelImages(NamedTuple):
    """A pyramid level's images: the reference for NCC (Wallis-filtered), the reference's raw grey values (edges)
    and the search images."""

    ref: np.ndarray
    raw: np.ndarray
    searches: list[Any]


def match_level(images: LevelImages, models, level, params, hr, guide, edge_mask=None):
    """One level (module docstring, step 2): dict with x, y (level px), h, per search image x/y/rho
    arrays (n, m) (NaN where not matched)."""
    ref, ref_raw, searches = images
    s = float(FACTOR) ** level
    lm = [LevelModel(m, s) for m in models]
    rho_min = params.rho_min if level == 0 else params.rho_min_coarse
    border = max(params.windows) // 2 + 2
    x, y = primitives(ref, level, params, border)
    n, m = len(x), len(searches)
    h_lo, h_hi, sens = height_interval(lm, x, y, params, hr, guide)
    # the previous level's TIN roughness in px of parallax, less (in quadrature) its median, the
    # matching noise that the roughness of plane residuals includes
    rough_px = np.zeros(n) if guide is None else guide.at(x * s, y * s)[1] * sens
    rough_px = np.sqrt(np.maximum(rough_px**2 - np.median(rough_px) ** 2, 0.0)) if n else rough_px
    halves = window_halves(
        ref_raw,
        x,
        y,
        params.windows,
        noise_sigma(ref_raw),
        params.precision,
        rough_px**2 / (params.coarse_grid * FACTOR),
    )
    rho_min = rho_thresholds(rho_min, params.rho_drop, rough_px)
    across = max(1, int(math.ceil(params.across / s)))
    cands = [
        candidates(
            ImagePair(ref, searches[k], lm[0], lm[k + 1]),
            x,
            y,
            (h_lo, h_hi),
            halves,
            across,
            rho_min,
            params.max_candidates,
        )
        for k in range(m)
    ]
    agree = params.agree_px / sens
    shifts, heights = estimate_shift(lm, x, y, cands, rho_min, params.peak_ratio)
    for c, hk in zip(cands, heights):
        c["h"] = hk
    h, score, i1, i2 = hypotheses(cands, agree)
    choice = unique_choice(h, score, i1, i2, cands, params.peak_ratio, params.margin)
    spacing = params.grid if level == 0 else params.coarse_grid
    choice = relax(
        x, y, (h, score), choice, np.maximum(agree, 1e-3), params.relax_radius * spacing, edge_mask=edge_mask
    )
    rows = np.arange(n)
    c = np.maximum(choice, 0)
    out = {
        "x": x,
        "y": y,
        "h": np.where(choice >= 0, h[rows, c], np.nan),
        "sx": np.full((n, m), np.nan),
        "sy": np.full((n, m), np.nan),
        "rho": np.full((n, m), np.nan),
        "candidates": int(np.isfinite(h).any(axis=1).sum()),
        "shifts": shifts * s,
    }
    for k, idx in enumerate((i1, i2)[:m]):
        j = np.where(choice >= 0, idx[rows, c], -1)
        has = j >= 0
        sel = np.flatnonzero(has)
        cx = cands[k]["x"][sel, j[sel]]
        cy = cands[k]["y"][sel, j[sel]]
        d = back_match(
            ImagePair(ref, searches[k], lm[0], lm[k + 1]),
            x[sel],
            y[sel],
            cx,
            cy,
            (h_lo[sel], h_hi[sel]),
            halves[sel],
            across,
        )
        ok = d <= params.back_px
        sel = sel[ok]
        out["sx"][sel, k], out["sy"][sel, k] = cx[ok], cy[ok]
        out["rho"][sel, k] = cands[k]["rho"][sel, j[sel]]
    matched = np.isfinite(out["sx"]).any(axis=1)
    for key in ("x", "y", "h", "sx", "sy", "rho"):
        out[key] = out[key][matched]
    return out


def height_interval(lm, x, y, params, hr, guide):
    """(h_lo, h_hi, px of parallax per m) of level points (x, y): the block's range + top_margin_px at
    the top level, below it the guide's height +- (tol_px of parallax + its roughness)."""
    s = lm[0].scale
    hmid = 0.5 * (hr[0] + hr[1])
    sens = np.max([parallax_per_metre(lm[0], mk, x, y, hmid) for mk in lm[1:]], axis=0)
    sens = np.where(np.isfinite(sens) & (sens > 0), sens, np.nanmedian(sens))
    if guide is None:
        pad = params.top_margin_px / sens
        return np.full(len(x), hr[0]) - pad, np.full(len(x), hr[1]) + pad, sens
    h0, rough = guide.at(x * s, y * s)
    tol = params.tol_px / sens + rough
    return h0 - tol, h0 + tol, sens


def match_level_edges(ref, searches, models, level, params, hr, guide, chains):
    """Edge points of one level (step 2): the chains' edgels matched into every search image
    (edges.match_edges, figural continuity) over the height interval of `height_interval`; kept
    where ok in every search image with heights agreeing within agree_px of parallax (height: the
    rho-weighted mean). Returns match_level's keys (x, y, h, sx, sy, rho) and chain, index."""
    lm = [LevelModel(mk, float(FACTOR) ** level) for mk in models]
    m = len(searches)
    pts = np.concatenate(chains) if chains else np.zeros((0, 2))
    lo, hi, _ = height_interval(lm, pts[:, 0], pts[:, 1], params, hr, guide)
    rho_min = params.rho_min if level == 0 else params.rho_min_coarse
    recs = [
        match_edges(
            ref,
            searches[k],
            chains,
            lambda c, r, h, k=k: predict(lm[0], lm[k + 1], c, r, h),
            (lo, hi),
            EdgeMatching(params.edge_window, params.edge_step, rho_min),
        )
        for k in range(m)
    ]
    x, y = recs[0]["col"], recs[0]["row"]
    ok = np.logical_and.reduce([r["ok"] for r in recs])
    rho = np.column_stack([r["rho"] for r in recs]).astype(float)
    hk = np.column_stack([r["h"] for r in recs])
    h = (rho * hk).sum(axis=1) / rho.sum(axis=1)
    if m > 1 and ok.any():
        _, _, sens = height_interval(lm, x[ok], y[ok], params, hr, guide)
        idx = np.flatnonzero(ok)
        ok[idx] = np.abs(hk[idx, 0] - hk[idx, 1]) <= params.agree_px / sens
    return {
        "x": x[ok],
        "y": y[ok],
        "h": h[ok],
        "rho": rho[ok],
        "sx": np.column_stack([r["col2"] for r in recs])[ok],
        "sy": np.column_stack([r["row2"] for r in recs])[ok],
        "chain": recs[0]["chain"][ok],
        "index": recs[0]["index"][ok],
        "edgels": len(x),
    }


def edge_breaklines(edge, scale, step):
    """Breaklines (full px x, y, h) of the matched edgels: runs of consecutive edgels of a chain."""
    if len(edge["x"]) < 2:
        return []
    cut = np.flatnonzero((np.diff(edge["chain"]) != 0) | (np.diff(edge["index"]) != step)) + 1
    line = np.column_stack([edge["x"] * scale, edge["y"] * scale, edge["h"]])
    return [part for part in np.split(line, cut) if len(part) >= 2]
