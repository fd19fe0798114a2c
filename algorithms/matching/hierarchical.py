"""Coarse-to-fine multi-primitive matching with MPGC, the second dense-matching strategy (paper Z,
Zhang & Gruen; methods.md section 6; issue 7).

0. Tiles: a reference image larger than `tile` px is cut into tiles (`_tiles`), each matched with
   TILE_MARGIN px of context in windows of the adapted images (the search windows from the
   models' prediction over the height range), each keeping the points of its core; the
   orientation bias of step 2 is estimated per tile. Memory is bounded by the tile size.
1. Preprocessing (preprocess.py): the reference (nadir) is low-passed to the search images'
   footprint (region_growing.adapt_resolution), every image Wallis-filtered and reduced to a
   factor-3 pyramid; the number of levels brings the parallax range of the block's height range
   to about `search_px_at_top` px at the top level (preprocess.levels_for), as far as the top
   level keeps 3 of the largest windows across the smallest image.
2. Per level, primitives of the reference: Foerstner points (one per `patch` x `patch` cell) and
   grid points (`grid` px apart at level 0, `coarse_grid` above); each is searched in every
   search image by NCC along its quasi-epipolar path (hierarchical_level.candidates) over a height
   interval: the block's range at the top, below it the previous level's TIN height +- (`tol_px`
   px of parallax + the TIN roughness there). Window per point from its texture and, below the
   top level, the TIN's terrain roughness (its roughness less, in quadrature, the level's median,
   the matching noise; hierarchical_level.window_halves, Kanade-Okutomi); rho threshold per level
   (`rho_min` at level 0, `rho_min_coarse` above) lowered by up to `rho_drop` where that roughness
   reaches 1 px of parallax (hierarchical_level.rho_thresholds); up to `max_candidates` candidates
   per image, resolved by the third image (height agreement), the peak ratio and relaxation
   (relaxation.py), then back-matching in every search image (a failing image drops out of the
   point). The orientation bias of each search image (constant image shift) is estimated per
   level from the unique candidates (estimate_shift) and compensated from then on
   (hierarchical_level.ShiftedModel), MPGC included.
   With `edges`, Canny edges of the reference level image (edges.canny, default thresholds) bound
   the relaxation: neighbours across an edge are left out. With `edge_points` (levels >=
   `edge_min_level`), the edges linked into chains (edges.link) are matched edgel by edgel (every
   `edge_step`-th) into every search image with the figural continuity constraint
   (edges.match_edges) over the same height interval, with the level models after this level's
   shift update; edgels ok in every search image whose heights agree within agree_px of parallax
   are extra points of the level (flag EDGE; at level 0 they go through MPGC like the others).
3. A TIN of the accepted points (reference image position at full resolution, height) with the
   blunder filter of surface/tin.py guides the next level; with `breaklines` the matched edge
   chains (runs of consecutive ok edgels) are conforming breaklines of it (tin.conform_breaklines)
   instead of mass points, so triangles do not bridge building steps.
4. Level 0's points go through MPGC (mpgc.match_points) in all their images at once. Points MPGC
   does not accept but that converged within the shift limit keep MPGC's positions with its
   lowered reliability (mpgc.py: rho x ellipse and geometric-test ratios; mostly an ellipse just
   over the limit); the others keep their NCC positions with the low reliability NCC_RELIABILITY
   x rho; both are flagged NCC_ONLY (not accepted). On the simulated triplet's 10 m DSM
   (test_hierarchical.py) MPGC's positions took the open-class RMS from bare 2.08 / crops 2.89 m
   (NCC's) to 1.82 / 2.33 m at the same coverage (1.71 / 2.28 m since MPGC's robust weights and the
   TIN-adapted windows; region growing 1.79 / 2.37 m); dropping the points near accepted ones
   instead (tried: within 10 px) lowers the coverage and not the RMS.
5. Output: MultiPoints (points.py) with group 3 (reference + 2 search images) or 1 (reference + 1),
   rho_min = the reliability (MPGC's, mpgc.py, or the NCC one), flags COMB_A / COMB_B for the
   search images 1 / 2 observed (+ NCC_ONLY), stats with provenance "hierarchical" and the
   timings per level.

Edges, measured on the simulated triplet's 10 m DSM (test_hierarchical.py, against the version
without them): the edge mask (on by default) changes little. Edge points at level 1 with
breaklines gave bare coverage 88 -> 89 %, RMS 2.27 -> 2.17 m, crops 80 -> 81 %, low texture
56 -> 58 %, building-edge MAE 4.32 -> 4.33 m (region growing 4.40; the 10 m TIN DEM smooths the
steps whatever the points), and nothing measurable once every path is sampled at its own spacing;
on the Ventoux pair (forest slope, tests/real/test_hierarchical_real.py) they add gross blunders
(2 m DSM - SRTM NMAD 10.7 -> 13.4 m, minimum -15 -> -352 m), so `edge_points` (and with it the
breaklines, which come from the matched edges) is off by default. Edge points at level 0 too
(edge_min_level 0) are the most accurate points (0.19 px RMS, none > 1 px on open ground) and lower the open-class RMS further
(bare 2.10, crops 2.74 m) but cost DEM coverage (bare 84, crops 70, low texture 43 %): the DEM's
blunder filter takes its robust sigma over all points, and the dense, precise edge points shrink
it, so more of the other points go.

Not yet (issue 7): tiling (the pyramids are whole-image arrays)."""
import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from .. import progress
from ..errors import InputError
from ..surface.tin import conform_breaklines, delaunay, filter_blunders, neighbour_residuals
from ..surface.tin_grid import Grid, rasterize
from . import preprocess
from .edges import canny, link, match_edges
from .hierarchical_level import (
    LevelModel,
    ShiftedModel,
    back_match,
    candidates,
    noise_sigma,
    rho_thresholds,
    window_halves,
)
from .imagery import Window, as_image
from .interest import interest_points
from .mpgc import MpgcParams, accepted, match_points
from .params import GrowParams
from .points import COMB_A, COMB_B, EDGE, NCC_ONLY, OBS_DTYPE, POINT_DTYPE, MultiPoints
from .relaxation import hypotheses, relax, unique_choice
from .seeds import predict, resolve_height_range

#: reliability of a point that failed MPGC: this factor x its smallest NCC rho
NCC_RELIABILITY = 0.25
FACTOR = 3


#: the largest window (pixels) matched in one piece, the search windows of a tile included: each is held
#: whole with its pyramids, candidates and level TINs (peak ~70 bytes a pixel of the three images: 2.2 GB
#: for the 20 km triplet's 4000 px images matched whole, 1.0 GB in tiles of 2048 px; bench_hierarchical)
MAX_PIXELS = 40_000_000
#: px of the reference image around a tile's core matched with it (context for the windows, the
#: relaxation and the TINs; its points are dropped) and added around the search windows
TILE_MARGIN = 256


@dataclass
class HierParams:
    """Parameters of the coarse-to-fine matcher (module docstring)."""

    search_px_at_top: float = 4.0      # parallax range (px) at the top level
    grid: int = 10                     # px between grid points at level 0
    coarse_grid: int = 6               # px between grid points above level 0
    patch: int = 16                    # px: one Foerstner point per patch x patch cell (every level)
    windows: tuple = (9, 15, 21)       # candidate window sizes (px, every level)
    precision: float = 0.05            # px: window choice target (hierarchical_level.window_halves)
    rho_min: float = 0.7               # NCC threshold at level 0
    rho_min_coarse: float = 0.6        # NCC threshold above level 0
    rho_drop: float = 0.1              # NCC threshold lowered by up to this where the TIN is rough (1 px parallax)
    max_candidates: int = 5
    peak_ratio: float = 0.9            # second / first peak below this: unique
    margin: float = 0.05               # score margin of the best hypothesis: unique
    agree_px: float = 1.0              # px of parallax: two images' heights agree
    tol_px: float = 3.0                # px of parallax around the TIN height below the top level
    across: float = 3.0                # px (full resolution) searched across the path
    top_margin_px: float = 2.0         # px of parallax added to the height range at the top level
    back_px: float = 1.0               # px (level): back-matching tolerance
    relax_radius: float = 3.0          # in grid spacings
    blunder_k: float = 4.0             # TIN blunder filter, robust sigmas
    wallis: bool = True
    tile: int = 4096                   # px: square tiles of the reference image (cores; memory: MAX_PIXELS)
    edges: bool = True                 # relaxation does not cross the reference level's Canny edges (step 2)
    edge_points: bool = False          # edge chains matched with figural continuity become points (step 2; off:
    #                                    module docstring, Ventoux)
    breaklines: bool = True            # matched edge chains are breaklines of the level TIN (step 3)
    edge_window: int = 7               # px: NCC window of edge matching (every level)
    edge_step: int = 2                 # every edge_step-th edgel of a chain is matched
    edge_min_length: int = 10          # px: shorter edge chains are dropped
    edge_min_level: int = 1            # edge points on this pyramid level and above (module docstring, step 2)
    final: MpgcParams = field(default_factory=lambda: MpgcParams(sigma_geometry=0.5))   # MPGC

    def check(self):
        if self.grid < 2 or self.coarse_grid < 2 or self.patch < 3:
            raise InputError("grid spacings must be >= 2 px and the Foerstner patch >= 3 px")
        if not self.windows or any(int(w) < 5 or int(w) % 2 == 0 for w in self.windows):
            raise InputError(f"window sizes must be odd and >= 5 px, got {self.windows}")
        lowest = min(self.rho_min, self.rho_min_coarse)
        if not (0 < self.rho_min < 1 and 0 < self.rho_min_coarse < 1 and 0 <= self.rho_drop < lowest):
            raise InputError("rho thresholds must lie between 0 and 1, and rho_drop between 0 and the thresholds")
        if self.edge_window < 3 or self.edge_window % 2 == 0 or self.edge_step < 1 or self.edge_min_length < 2 \
                or self.edge_min_level < 0:
            raise InputError("the edge window must be odd and >= 3 px, the edgel step >= 1, the chain length >= 2 "
                             "and the edge level >= 0")
        if self.tile < 2 * TILE_MARGIN:
            raise InputError(f"tiles must be at least {2 * TILE_MARGIN} px, got {self.tile}")
        if self.max_candidates < 1 or self.search_px_at_top <= 0 or self.tol_px <= 0 or self.agree_px <= 0:
            raise InputError("max_candidates, search_px_at_top, tol_px and agree_px must be positive")
        self.final.check()
        return self


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
        neighbour_residuals(indptr, indices, *(np.ascontiguousarray(v, float) for v in (x, y, h)),
                            np.ones(len(h), bool), rough)
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
    if level == 0:    # region growing's lattice (half template 9): comparable nodes
        gx = np.arange(9.5, cols - border, params.grid)
        gy = np.arange(9.5, rows - border, params.grid)
    else:
        gx = np.arange(border + 0.5, cols - border, params.coarse_grid)
        gy = np.arange(border + 0.5, rows - border, params.coarse_grid)
    gx, gy = (v.ravel() for v in np.meshgrid(gx, gy))
    inside = (gx >= border) & (gy >= border)
    x, y = np.concatenate([px, gx[inside]]), np.concatenate([py, gy[inside]])
    first = np.sort(np.unique(np.column_stack([x, y]), axis=0, return_index=True)[1])   # a Foerstner point on a node
    return x[first], y[first]


def match_level(ref, ref_raw, searches, models, level, params, hr, guide, edge_mask=None):
    """One level (module docstring, step 2): dict with x, y (level px), h, per search image x/y/rho
    arrays (n, m) (NaN where not matched)."""
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
    rough_px = np.sqrt(np.maximum(rough_px ** 2 - np.median(rough_px) ** 2, 0.0)) if n else rough_px
    halves = window_halves(ref_raw, x, y, params.windows, noise_sigma(ref_raw), params.precision,
                           rough_px ** 2 / (params.coarse_grid * FACTOR))
    rho_min = rho_thresholds(rho_min, params.rho_drop, rough_px)
    across = max(1, int(math.ceil(params.across / s)))
    cands = [candidates(ref, searches[k], lm[0], lm[k + 1], x, y, h_lo, h_hi, halves, across, rho_min,
                        params.max_candidates) for k in range(m)]
    agree = params.agree_px / sens
    shifts, heights = estimate_shift(lm, x, y, cands, rho_min, params.peak_ratio)
    for c, hk in zip(cands, heights):
        c["h"] = hk
    h, score, i1, i2 = hypotheses(cands, agree)
    choice = unique_choice(h, score, i1, i2, cands, params.peak_ratio, params.margin)
    spacing = params.grid if level == 0 else params.coarse_grid
    choice = relax(x, y, h, score, choice, np.maximum(agree, 1e-3), params.relax_radius * spacing,
                   edge_mask=edge_mask)
    rows = np.arange(n)
    c = np.maximum(choice, 0)
    out = {"x": x, "y": y, "h": np.where(choice >= 0, h[rows, c], np.nan),
           "sx": np.full((n, m), np.nan), "sy": np.full((n, m), np.nan), "rho": np.full((n, m), np.nan),
           "candidates": int(np.isfinite(h).any(axis=1).sum()), "shifts": shifts * s}
    for k, idx in enumerate((i1, i2)[:m]):
        j = np.where(choice >= 0, idx[rows, c], -1)
        has = j >= 0
        sel = np.flatnonzero(has)
        cx = cands[k]["x"][sel, j[sel]]
        cy = cands[k]["y"][sel, j[sel]]
        d = back_match(ref, searches[k], lm[0], lm[k + 1], x[sel], y[sel], cx, cy, h_lo[sel], h_hi[sel],
                       halves[sel], across)
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
    recs = [match_edges(ref, searches[k], chains, lambda c, r, h, k=k: predict(lm[0], lm[k + 1], c, r, h), (lo, hi),
                        window=params.edge_window, step=params.edge_step, rho_min=rho_min) for k in range(m)]
    x, y = recs[0]["col"], recs[0]["row"]
    ok = np.logical_and.reduce([r["ok"] for r in recs])
    rho = np.column_stack([r["rho"] for r in recs]).astype(float)
    hk = np.column_stack([r["h"] for r in recs])
    h = (rho * hk).sum(axis=1) / rho.sum(axis=1)
    if m > 1 and ok.any():
        _, _, sens = height_interval(lm, x[ok], y[ok], params, hr, guide)
        idx = np.flatnonzero(ok)
        ok[idx] = np.abs(hk[idx, 0] - hk[idx, 1]) <= params.agree_px / sens
    return {"x": x[ok], "y": y[ok], "h": h[ok], "rho": rho[ok],
            "sx": np.column_stack([r["col2"] for r in recs])[ok], "sy": np.column_stack([r["row2"] for r in recs])[ok],
            "chain": recs[0]["chain"][ok], "index": recs[0]["index"][ok], "edgels": len(x)}


def edge_breaklines(edge, scale, step):
    """Breaklines (full px x, y, h) of the matched edgels: runs of consecutive edgels of a chain."""
    if len(edge["x"]) < 2:
        return []
    cut = np.flatnonzero((np.diff(edge["chain"]) != 0) | (np.diff(edge["index"]) != step)) + 1
    line = np.column_stack([edge["x"] * scale, edge["y"] * scale, edge["h"]])
    return [part for part in np.split(line, cut) if len(part) >= 2]


def adapted_images(images, models, hr, grow=None):
    """The images, the finer of each reference-search pair low-passed to the coarser one's
    resolution (region_growing.adapt_resolution with `grow`'s PSF settings, default GrowParams();
    Image-like, read by windows)."""
    grow = grow or GrowParams()
    ref, s1 = _adapt(images[0], images[1], models[0], models[1], grow, hr)
    adapted = [ref, s1]
    if len(images) == 3:
        adapted.append(_adapt(images[0], images[2], models[0], models[2], grow, hr)[1])
    return adapted


def _pyramids(adapted, models, hr, params):
    """Per image (NCC pyramid, raw pyramid) of the adapted images; levels; parallax range (px)."""
    cols, rows = models[0].size
    cx, cy = np.array([0.5 * cols]), np.array([0.5 * rows])
    parallax = max(float(np.hypot(*(np.subtract(predict(models[0], mk, cx, cy, np.array([hr[1]])),
                                                predict(models[0], mk, cx, cy, np.array([hr[0]]))))))
                   for mk in models[1:])
    levels = preprocess.levels_for(parallax if math.isfinite(parallax) else 0.0, params.search_px_at_top, FACTOR)
    # the top level keeps at least 3 of the largest windows across the smallest image
    smallest = min(min(m.size) for m in models)
    levels = max(1, min(levels, int(math.floor(math.log(max(smallest / (3 * max(params.windows)), 1.0), FACTOR))) + 1))
    largest = max(int(np.prod(image.size)) for image in adapted)
    if largest > MAX_PIXELS:
        raise InputError(f"a search window of the coarse-to-fine strategy would be {largest / 1e6:.0f} Mpx (at most "
                         f"{MAX_PIXELS / 1e6:.0f} Mpx are held at once): narrow the terrain height range or make the "
                         "tiles smaller")
    pyr = []
    for image in adapted:
        raw = image.read(0, 0, *image.size)[0]
        ncc = preprocess.wallis(raw) if params.wallis else raw
        pyr.append((preprocess.pyramid(ncc, levels, FACTOR), preprocess.pyramid(raw, levels, FACTOR)))
    return pyr, levels, parallax


def _adapt(image0, image, model0, model, grow, hr):
    from .region_growing import adapt_resolution
    return adapt_resolution(as_image(image0), as_image(image), model0, model, grow, hr)


def match_hierarchical(images, models, names=None, image_ids=None, params=None, height_range=None, feedback=None):
    """Coarse-to-fine multi-primitive matching with MPGC of 2 or 3 images (reference/nadir first,
    then the search images; paths, arrays or Images) with their sensor models. A reference image
    larger than `params.tile` px is matched tile by tile (`_tiles`). Returns MultiPoints (module
    docstring, step 5). Raises InputError on unusable input, CancelledError when cancelled."""
    params = (params or HierParams()).check()
    n = len(images)
    if n not in (2, 3) or len(models) != n:
        raise InputError(f"the coarse-to-fine matcher takes 2 or 3 images (reference, search[, search]), got {n}")
    names = list(names or [f"image {k + 1}" for k in range(n)])
    image_ids = list(image_ids or range(1, n + 1))
    hr = resolve_height_range(models[0], height_range)
    progress.step(feedback, 0, "coarse-to-fine matching: preprocessing (resolution adaptation, Wallis, pyramids)")
    adapted = adapted_images(images, models, hr)
    boxes = _tiles(models[0].size, params.tile)
    if len(boxes) == 1:
        out, stats = _match(adapted, models, params, hr, feedback)
    else:
        out, stats = _match_tiles(adapted, models, params, hr, boxes, feedback)
    points = to_multipoints(out, image_ids, stats)
    progress.step(feedback, 100.0, f"coarse-to-fine matching of {', '.join(names)}: {len(points)} points, "
                  f"{int(np.count_nonzero(~out['mpgc_ok']))} of them not accepted by MPGC (low reliability)")
    return points


def _tiles(size, tile):
    """Cores (x0, y0, x1, y1) of the square tiles of an image of `size` (one: the whole image)."""
    cols, rows = size
    nx, ny = max(1, math.ceil(cols / tile)), max(1, math.ceil(rows / tile))
    xs, ys = np.linspace(0, cols, nx + 1).round().astype(int), np.linspace(0, rows, ny + 1).round().astype(int)
    return [(xs[i], ys[j], xs[i + 1], ys[j + 1]) for j in range(ny) for i in range(nx)]


def _tile_windows(adapted, models, core, hr, grid):
    """Windows (imagery.Window) and window models (ShiftedModel) of one tile: the reference core
    plus TILE_MARGIN (its corner on a multiple of `grid`, so level 0's grid points are the whole
    image's), and per search image the box its models predict for it over the height range plus
    TILE_MARGIN, clipped to the images; None where a search window is empty."""
    def clip(box, size):
        x0, y0 = max(int(math.floor(box[0])), 0), max(int(math.floor(box[1])), 0)
        x1, y1 = min(int(math.ceil(box[2])), size[0]), min(int(math.ceil(box[3])), size[1])
        return (x0, y0, x1, y1) if min(x1 - x0, y1 - y0) >= TILE_MARGIN // 2 else None

    ref = clip((max(core[0] - TILE_MARGIN, 0) // grid * grid, max(core[1] - TILE_MARGIN, 0) // grid * grid,
                core[2] + TILE_MARGIN, core[3] + TILE_MARGIN), models[0].size)
    gx, gy = (v.ravel() for v in np.meshgrid(np.linspace(ref[0], ref[2], 5), np.linspace(ref[1], ref[3], 5)))
    boxes = [ref]
    for mk in models[1:]:
        with np.errstate(invalid="ignore"):
            xy = [predict(models[0], mk, gx, gy, np.full(gx.size, h)) for h in hr]
        x = np.concatenate([v[0] for v in xy])
        y = np.concatenate([v[1] for v in xy])
        if not np.isfinite(x).any():
            return None
        box = clip((np.nanmin(x) - TILE_MARGIN, np.nanmin(y) - TILE_MARGIN, np.nanmax(x) + TILE_MARGIN,
                    np.nanmax(y) + TILE_MARGIN), mk.size)
        if box is None:
            return None
        boxes.append(box)
    windows = [Window(image, b[0], b[1], b[2] - b[0], b[3] - b[1]) for image, b in zip(adapted, boxes)]
    wmodels = [ShiftedModel(mk, -b[0], -b[1], (b[2] - b[0], b[3] - b[1])) for mk, b in zip(models, boxes)]
    return windows, wmodels, boxes


def _match_tiles(adapted, models, params, hr, cores, feedback):
    """`_match` per tile (`_tile_windows`); each tile keeps the points of its core, in image
    coordinates. A tile where too few points match is left empty with a message."""
    log = progress.ensure(feedback)
    parts, tiles, failures = [], [], []
    for k, core in enumerate(cores):
        sub = progress.scaled(feedback, 100.0 * k / len(cores), 100.0 * (k + 1) / len(cores))
        progress.step(sub, 0.0, f"coarse-to-fine matching: tile {k + 1} of {len(cores)} {core}")
        tile = _tile_windows(adapted, models, core, hr, int(params.grid))
        if tile is None:
            log.pushInfo(f"tile {k + 1} {core}: outside the search images, skipped")
            continue
        windows, wmodels, boxes = tile
        try:
            out, stats = _match(windows, wmodels, params, hr, sub)
        except InputError as exc:
            log.pushInfo(f"tile {k + 1} {core}: no points ({exc})")
            failures.append(str(exc))
            continue
        out["x0"] += boxes[0][0]
        out["y0"] += boxes[0][1]
        for j, b in enumerate(boxes[1:]):
            out["sx"][:, j] += b[0]
            out["sy"][:, j] += b[1]
        mine = (out["x0"] >= core[0]) & (out["x0"] < core[2]) & (out["y0"] >= core[1]) & (out["y0"] < core[3])
        parts.append({key: v[mine] for key, v in out.items()})
        tiles.append({"core": [int(v) for v in core], "points": int(mine.sum()), **stats})
    if not parts:
        raise InputError("no tile of the reference image gave points" + (f" ({failures[0]})" if failures else
                                                                         " (none lies inside the search images)"))
    out = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    seconds = {}
    for t in tiles:
        for key, v in t["seconds"].items():
            seconds[key] = round(seconds.get(key, 0.0) + v, 3)
    stats = {"provenance": "hierarchical", "tiles": len(cores), "tiles_matched": len(tiles), "seconds": seconds,
             "mpgc_failed": int(np.count_nonzero(~out["mpgc_ok"])), "edge_points": int(np.count_nonzero(out["edge"])),
             "per_tile": [{key: t[key] for key in ("core", "points", "levels", "search_image_shifts_px")}
                          for t in tiles]}
    return out, stats


def _match(adapted, models, params, hr, feedback):
    """The coarse-to-fine matching of one piece (the images or the windows of a tile): (the final
    points `_final`, statistics)."""
    log = progress.ensure(feedback)
    n = len(adapted)
    t0 = time.perf_counter()
    pyr, levels, parallax = _pyramids(adapted, models, hr, params)
    timings = {"preprocessing": time.perf_counter() - t0}
    log.pushInfo(f"{levels} pyramid levels (factor {FACTOR}) for a parallax range of {parallax:.1f} px")
    guide, result = None, None
    counts, edge_counts = {}, {}
    shifts = np.zeros((n - 1, 2))
    for level in range(levels - 1, -1, -1):
        t = time.perf_counter()
        progress.step(feedback, 80.0 * (levels - 1 - level) / levels)
        current = [models[0]] + [ShiftedModel(mk, *d) for mk, d in zip(models[1:], shifts)]
        ref, searches = pyr[0][0][level], [p[0][level] for p in pyr[1:]]
        mask, chains = None, []
        if params.edges or params.edge_points:
            mask = canny(pyr[0][1][level])
            chains = link(mask, params.edge_min_length)
        result = match_level(ref, pyr[0][1][level], searches, current, level, params, hr, guide,
                             edge_mask=mask if params.edges else None)
        shifts = shifts + result["shifts"]
        s = float(FACTOR) ** level
        if len(result["x"]) < 3:
            raise InputError(f"level {level}: only {len(result['x'])} points matched; check the images, the models "
                             "and the height range")
        result["edge"] = np.zeros(len(result["x"]), bool)
        lines = []
        if params.edge_points and chains and level >= params.edge_min_level:
            edge = match_level_edges(ref, searches, [models[0]] + [ShiftedModel(mk, *d) for mk, d in
                                                                   zip(models[1:], shifts)],
                                     level, params, hr, guide, chains)
            edge_counts[f"level {level}"] = {"chains": len(chains), "edgels": edge["edgels"],
                                             "matched": int(len(edge["x"]))}
            if params.breaklines:
                lines = edge_breaklines(edge, s, params.edge_step)
            edge["edge"] = np.ones(len(edge["x"]), bool)
            for key in ("x", "y", "h", "sx", "sy", "rho", "edge"):
                result[key] = np.concatenate([result[key], edge[key]])
        timings[f"level {level}"] = time.perf_counter() - t
        counts[f"level {level}"] = int(len(result["x"]))
        if level > 0:     # the TIN guides the next level
            mass = ~result["edge"] if lines else np.ones(len(result["x"]), bool)
            guide = TinGuide(result["x"][mass] * s, result["y"][mass] * s, result["h"][mass], pyr[0][0][0].shape,
                             max(s / FACTOR, 1.0), params.blunder_k, lines, spacing=s)
        log.pushInfo(f"level {level}: {len(result['x'])} points ({int(result['edge'].sum())} on edges) "
                     f"in {timings[f'level {level}']:.2f} s")
    progress.step(feedback, 80.0, f"MPGC of {len(result['x'])} points")
    t = time.perf_counter()
    log.pushInfo("orientation bias of the search images (px): " + ", ".join(f"({d[0]:.2f}, {d[1]:.2f})"
                                                                          for d in shifts))
    out = _final(adapted, [models[0]] + [ShiftedModel(mk, *d) for mk, d in zip(models[1:], shifts)], result, params)
    timings["mpgc"] = time.perf_counter() - t
    stats = {"provenance": "hierarchical", "levels": levels, "points_per_level": counts,
             "seconds": {k: round(v, 3) for k, v in timings.items()},
             "mpgc_failed": int(np.count_nonzero(~out["mpgc_ok"])), "edges_per_level": edge_counts,
             "edge_points": int(np.count_nonzero(out["edge"])),
             "edge_points_mpgc": int(np.count_nonzero(out["edge"] & out["mpgc_ok"])),
             "search_image_shifts_px": shifts.round(3).tolist()}
    return out, stats


def _final(adapted, models, result, params):
    """MPGC of level 0's points in the images each was matched in (module docstring, step 4)."""
    x0, y0, h = result["x"], result["y"], result["h"]
    m = result["sx"].shape[1]
    lon, lat = models[0].image_to_ground(x0, y0, h)
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    sx, sy, rho = result["sx"].copy(), result["sy"].copy(), result["rho"].copy()
    ok = np.zeros(len(x0), bool)
    rel = np.full(len(x0), np.nan)
    ellipse = np.zeros((len(x0), m, 2))
    present = np.isfinite(sx)
    for combo in {tuple(np.flatnonzero(p)) for p in present}:
        idx = np.flatnonzero((present == np.isin(np.arange(m), combo)).all(axis=1))
        rec = match_points(adapted[0], [adapted[k + 1] for k in combo], [models[0]] + [models[k + 1] for k in combo],
                                x0[idx], y0[idx], lon[idx], lat[idx], h[idx], params.final)
        good = accepted(rec, params.final)
        placed = rec["reliability"] > 0      # converged within the shift: MPGC's position, even if not accepted
        g = idx[placed]
        for c, k in enumerate(combo):
            sx[g, k], sy[g, k], rho[g, k] = rec["x"][placed, c], rec["y"][placed, c], rec["rho"][placed, c]
            ellipse[g, k] = np.column_stack([rec["semi_major"][placed, c], rec["semi_minor"][placed, c]])
        ok[idx[good]] = True
        rel[g] = rec["reliability"][placed]
    ncc = np.isnan(rel)
    rel[ncc] = NCC_RELIABILITY * np.nanmin(np.where(present, rho, np.nan), axis=1)[ncc]
    return {"x0": x0, "y0": y0, "sx": sx, "sy": sy, "rho": rho, "ellipse": ellipse, "reliability": rel,
            "mpgc_ok": ok, "edge": result.get("edge", np.zeros(len(x0), bool))}


def to_multipoints(out, image_ids, stats):
    """MultiPoints of the final points (module docstring, step 5)."""
    n, m = out["sx"].shape
    present = np.isfinite(out["sx"])
    points = np.zeros(n, POINT_DTYPE)
    points["id"] = np.arange(1, n + 1)
    points["group"] = np.where(present.sum(axis=1) == 2, 3, 1)
    points["flags"] = (present[:, 0] * COMB_A + (present[:, 1] * COMB_B if m > 1 else 0)
                       + (~out["mpgc_ok"]) * NCC_ONLY + out["edge"] * EDGE).astype(np.uint8)
    points["rho_min"] = out["reliability"]
    points["rho_a"] = out["rho"][:, 0]
    points["rho_b"] = out["rho"][:, 1] if m > 1 else np.nan
    points["rho_c"] = points["dx"] = points["dy"] = np.nan
    blocks = []
    obs = np.zeros(n, OBS_DTYPE)
    obs["point_id"], obs["image_id"] = points["id"], image_ids[0]
    obs["col"], obs["row"], obs["rho"] = out["x0"], out["y0"], np.nan
    blocks.append(obs)
    for k in range(m):
        obs = np.zeros(n, OBS_DTYPE)
        obs["point_id"], obs["image_id"] = points["id"], image_ids[k + 1]
        obs["col"], obs["row"], obs["rho"] = out["sx"][:, k], out["sy"][:, k], out["rho"][:, k]
        obs["semi_major"], obs["semi_minor"] = out["ellipse"][:, k, 0], out["ellipse"][:, k, 1]
        blocks.append(obs[present[:, k]])
    observations = np.concatenate(blocks)
    observations = observations[np.lexsort((observations["image_id"], observations["point_id"]))]
    stats = {**stats, "images": [int(i) for i in image_ids], "group3": int(np.count_nonzero(points["group"] == 3)),
             "group1": int(np.count_nonzero(points["group"] == 1))}
    return MultiPoints(points, observations, stats)
