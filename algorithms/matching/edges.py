"""Edges for the multi-primitive matcher (Zhang and Gruen 2004, section 3.3): Canny edge pixels, linked into chains,
matched edgel by edgel along quasi-epipolar segments with the figural continuity constraint.

- `canny`: Gaussian smoothing (normalised convolution, so nodata NaN does not bleed in), Sobel
  gradient (kernels / 8: DN per px), non-maximum suppression with interpolated neighbours,
  hysteresis (8-connected). Default thresholds: high = the 90th percentile of the gradient
  magnitude, low = 0.4 high, each at least 5 / 2.5 times the noise's gradient-component std (image
  noise from the median absolute 3 x 3 Laplacian difference, Immerkaer 1996, through the filter).
- `link`: staircase corners thinned, junctions (>= 3 neighbours) split the chains, which end on
  the junction pixel; chains shorter than min_length pixels dropped (Z: 15 px for satellites).
- `match_edges`: for every `step`-th edgel, candidates are the NCC maxima along the image-2 path
  predicted over the height range (template through the local affine of `predict`), kept when
  rho >= 0.5 and the gradient direction (modulo 2 pi) agrees within 40 degrees (Z steps a, b), at
  most 5 (none for edges within 30 degrees of parallel to the quasi-epipolar line); then per chain
  the candidate sequence that minimises unary cost + disparity jumps (dynamic programming, edgels
  may be skipped at a cost) replaces Zhang and Gruen's relaxation (figural continuity). An edgel is ok
  when its chosen rho >= rho_min and it agrees within 1 px with a chosen neighbour on its chain.
Positions are GDAL image coordinates (pixel (i, j) has its centre at (j + 0.5, i + 0.5))."""

import math
from typing import NamedTuple

import numpy as np
from scipy import ndimage

from ..errors import InputError
from . import edges_kernels as kernels

HIGH_PERCENTILE = 90.0  # default high threshold: this percentile of the gradient magnitude
LOW_RATIO = 0.4  # default low threshold / high threshold
NOISE_HIGH = 5.0  # thresholds at least these multiples of the noise's gradient-component std
NOISE_LOW = 2.5

GRADIENT_SIGMA = 1.0  # px, smoothing of the gradients compared in match_edges
CANDIDATES = 5  # candidates per edgel (Z: up to 5)
RHO_FLOOR = 0.5  # candidates need this correlation (Z step b)
MAX_ANGLE = 40.0  # degrees between predicted and found gradient directions (Z step a)
MIN_CROSSING = 30.0  # degrees: edges closer than this to parallel to the quasi-epipolar line are not matched
DIR_WEIGHT = 0.5  # unary cost = (1 - rho) + DIR_WEIGHT (1 - cos(angle))
PATH_STEP = 0.5  # px between NCC samples along the quasi-epipolar path
NODES = 17  # heights at which predict is called per edgel; positions in between linear
JUMP_COST = 0.5  # cost per px of disparity jump between consecutive matched edgels ...
JUMP_TOL = 0.5  # ... beyond this many px per `step` along the chain
SKIP_COST = 0.5  # cost of leaving out an edgel that has candidates
MAX_SKIP = 3  # edgels left out in a row inside a chain's path
CONTINUITY_TOL = 1.0  # px per step: an ok edgel agrees this well with a chosen neighbour
BLOCK = 8192  # edgels per block of candidate search (bounds the path arrays)

EDGEL_DTYPE = np.dtype(
    [
        ("chain", "i4"),
        ("index", "i4"),
        ("col", "f8"),
        ("row", "f8"),
        ("col2", "f8"),
        ("row2", "f8"),
        ("h", "f8"),
        ("rho", "f4"),
        ("ok", "?"),
    ]
)


def _image(img, name):
    a = np.asarray(img, dtype=np.float64)
    if a.ndim != 2 or min(a.shape) < 3:
        raise InputError(f"{name} must be a 2-D image of at least 3 x 3 pixels, got shape {a.shape}")
    return a


def _smooth(img, valid, sigma):
    """Gaussian of sigma px by normalised convolution over the valid pixels inside the image (NaN
    where none): neither nodata nor a replicated border enters."""
    if sigma <= 0:
        return np.where(valid, img, np.nan)
    num = ndimage.gaussian_filter(np.where(valid, img, 0.0), sigma, mode="constant", truncate=4.0)
    den = ndimage.gaussian_filter(valid.astype(np.float64), sigma, mode="constant", truncate=4.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-6, num / den, np.nan)


def gradients(img, sigma=1.0):
    """(gx, gy, ok): Sobel gradient / 8 (DN per px, +x = +col, +y = +row) of the Gaussian-smoothed
    image, 0 where not finite; ok = the pixel and its 3 x 3 neighbours are valid, off the border."""
    img = _image(img, "the image")
    valid = np.isfinite(img)
    s = _smooth(img, valid, sigma)
    gx = ndimage.sobel(s, axis=1, mode="nearest") / 8.0
    gy = ndimage.sobel(s, axis=0, mode="nearest") / 8.0
    ok = ndimage.binary_erosion(valid, np.ones((3, 3), bool), border_value=0)
    gx[~np.isfinite(gx)] = 0.0
    gy[~np.isfinite(gy)] = 0.0
    return gx, gy, ok


def noise_std(img):
    """Image noise std from the median absolute value of the 3 x 3 Laplacian difference
    [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] (std 6 sigma for white noise) over full valid stencils."""
    img = _image(img, "the image")
    k = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
    r = ndimage.correlate(np.nan_to_num(img), k, mode="nearest")[1:-1, 1:-1]
    full = ndimage.binary_erosion(np.isfinite(img), np.ones((3, 3), bool), border_value=0)[1:-1, 1:-1]
    if not full.any():
        return 0.0
    return float(np.median(np.abs(r[full]))) / (0.6745 * 6.0)


def _gradient_gain(sigma):
    """Std of one gradient component per unit std of white image noise (impulse response norm)."""
    r = int(math.ceil(4.0 * sigma)) + 3
    delta = np.zeros((2 * r + 1, 2 * r + 1))
    delta[r, r] = 1.0
    gx, _, _ = gradients(delta, sigma)
    return float(np.sqrt((gx**2).sum()))


def thresholds(img, sigma=1.0, low=None, high=None, mag=None, ok=None):
    """(low, high) hysteresis thresholds of canny (the defaults described in the module docstring)."""
    if mag is None:
        gx, gy, ok = gradients(img, sigma)
        mag = np.hypot(gx, gy)
    floor = noise_std(img) * _gradient_gain(sigma)
    if high is None:
        values = mag[ok]
        high = max(float(np.percentile(values, HIGH_PERCENTILE)) if values.size else 0.0, NOISE_HIGH * floor)
    if low is None:
        low = max(LOW_RATIO * high, min(NOISE_LOW * floor, high))
    low, high = float(low), float(high)
    if not (0 <= low <= high):
        raise InputError(f"the Canny thresholds must satisfy 0 <= low <= high, got low {low}, high {high}")
    return low, high


def canny(img, sigma=1.0, low=None, high=None):
    """Canny edge pixels (bool array of the image's shape): gradient of the image smoothed by a
    Gaussian of `sigma` px, non-maximum suppression, hysteresis between `low` and `high` (gradient
    magnitude in DN per px; defaults from the magnitude's percentiles and the noise). NaN pixels,
    their 3 x 3 neighbours and the image border are never edges."""
    img = _image(img, "the image")
    if not sigma >= 0:
        raise InputError(f"sigma must be >= 0 px, got {sigma}")
    gx, gy, ok = gradients(img, sigma)
    mag = np.hypot(gx, gy)
    low, high = thresholds(img, sigma, low, high, mag, ok)
    thin = np.empty(mag.shape, bool)
    kernels.nms(gx, gy, mag, ok, thin)
    out = np.empty(mag.shape, bool)
    kernels.hysteresis(thin & (mag >= low), thin & (mag >= high), out)
    return out


def link(edge_mask, min_length=10):
    """Chains of 8-connected edge pixels: list of (n, 2) float64 arrays of (col, row) pixel
    centres, ordered along the chain; junctions split chains (each chain ends on the junction
    pixel); a closed contour's last point neighbours its first; chains of < min_length points
    dropped."""
    mask = np.array(edge_mask, dtype=bool)
    if mask.ndim != 2:
        raise InputError(f"the edge mask must be 2-D, got shape {mask.shape}")
    if mask.size == 0 or not mask.any():
        return []
    kernels.thin_corners(mask)
    rows, cols, starts = kernels.trace(mask)
    return [
        np.column_stack([cols[a:b] + 0.5, rows[a:b] + 0.5]).astype(np.float64)
        for a, b in zip(starts[:-1], starts[1:])
        if b - a >= max(int(min_length), 1)
    ]


def _sample(chains, step, height_range):
    """Sampled edgels: chain id, index along the chain, col, row, h_lo, h_hi."""
    if step < 1:
        raise InputError(f"the edgel step must be >= 1, got {step}")
    arrays = []
    for c in chains:
        c = np.asarray(c, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != 2:
            raise InputError(f"a chain must be an (n, 2) array of (col, row), got shape {c.shape}")
        arrays.append(c)
    total = sum(len(c) for c in arrays)
    try:
        lo, hi = (np.broadcast_to(np.asarray(v, np.float64), (total,)) for v in height_range)
    except (TypeError, ValueError):
        raise InputError(
            "height_range must be (h_min, h_max): two numbers or two arrays with one value per "
            f"chain point ({total} in all)"
        ) from None
    if np.any(~(hi > lo)):
        raise InputError("height_range must have h_max > h_min (finite) everywhere")
    chain_id, index = [], []
    for k, c in enumerate(arrays):
        idx = np.arange(0, len(c), int(step))
        chain_id.append(np.full(idx.size, k))
        index.append(idx)
    chain_id = np.concatenate(chain_id) if arrays else np.empty(0, int)
    index = np.concatenate(index) if arrays else np.empty(0, int)
    first = np.cumsum([0] + [len(c) for c in arrays])[:-1].astype(int)
    points = np.concatenate(arrays) if total else np.empty((0, 2))
    flat = first[chain_id] + index if chain_id.size else np.empty(0, int)
    return chain_id, index, points[flat, 0], points[flat, 1], lo[flat], hi[flat]


def _paths(predict, x1, y1, lo, hi):
    """Quasi-epipolar paths: predict at NODES heights, positions every <= PATH_STEP px by linear
    interpolation. Returns (px, py, length) with px, py (n, m), length = the path's length in px."""
    nodes = np.linspace(0.0, 1.0, NODES)
    hn = lo[:, None] + (hi - lo)[:, None] * nodes
    shape = hn.shape
    qx, qy = predict(np.repeat(x1, NODES).reshape(shape), np.repeat(y1, NODES).reshape(shape), hn)
    qx, qy = np.asarray(qx, np.float64).reshape(shape), np.asarray(qy, np.float64).reshape(shape)
    length = np.hypot(np.diff(qx, axis=1), np.diff(qy, axis=1)).sum(axis=1)
    longest = np.nanmax(length) if np.isfinite(length).any() else 0.0
    m = max(3, int(math.ceil(longest / PATH_STEP)) + 1)
    u = np.linspace(0.0, NODES - 1.0, m)
    j0 = np.minimum(u.astype(int), NODES - 2)
    f = u - j0
    px = qx[:, j0] * (1.0 - f) + qx[:, j0 + 1] * f
    py = qy[:, j0] * (1.0 - f) + qy[:, j0 + 1] * f
    return np.ascontiguousarray(px), np.ascontiguousarray(py), length


def _affine(predict, x1, y1, h, d=1.0):
    """(n, 4) affine (a1, a2, a4, a5) = d(col2, row2) / d(col, row) at height h, central differences."""
    n = x1.size
    xs = np.concatenate([x1 + d, x1 - d, x1, x1])
    ys = np.concatenate([y1, y1, y1 + d, y1 - d])
    qx, qy = predict(xs, ys, np.tile(h, 4))
    qx, qy = np.asarray(qx, np.float64), np.asarray(qy, np.float64)
    px_, mx, py_, my = (slice(k * n, (k + 1) * n) for k in range(4))
    return np.ascontiguousarray(
        np.column_stack(
            [
                (qx[px_] - qx[mx]) / (2 * d),
                (qx[py_] - qx[my]) / (2 * d),
                (qy[px_] - qy[mx]) / (2 * d),
                (qy[py_] - qy[my]) / (2 * d),
            ]
        )
    )


class EdgeMatching(NamedTuple):
    """window: odd NCC template size (px); step: every step-th edgel of a chain is matched; rho_min: the lowest
    rho of a matched edgel; figural: figural continuity along the chain (False: each edgel's best candidate)."""

    window: int = 7
    step: int = 2
    rho_min: float = 0.7
    figural: bool = True


def match_edges(ref_img, search_img, chains, predict, height_range, settings=EdgeMatching()):
    """Matches every `step`-th edgel of each chain (from `link` on ref_img) into search_img (EdgeMatching
    `settings`).

    predict(col, row, h) -> (col2, row2) maps reference positions at height h into the search
    image (vectorised: arrays of one shape, NaN outside); height_range = (h_min, h_max), numbers or
    arrays with one value per chain point (e.g. from the previous level's TIN). window: odd NCC
    template size (px). figural=False takes each edgel's best candidate alone (plain best match,
    ok = rho >= rho_min). Returns an EDGEL_DTYPE array, one record per sampled edgel in chain order:
    chain, index (point of the chain), col, row; col2, row2, h, rho of the chosen candidate (the
    best one where the continuity left the edgel out, NaN where it had none); ok."""
    window, step, rho_min, figural = settings
    ref = _image(ref_img, "the reference image").astype(np.float32)
    search = _image(search_img, "the search image").astype(np.float32)
    if window < 3 or window % 2 == 0:
        raise InputError(f"the NCC window must be odd and >= 3 px, got {window}")
    chain_id, index, x1, y1, lo, hi = _sample(chains, step, height_range)
    n = x1.size
    out = np.zeros(n, EDGEL_DTYPE)
    out["chain"], out["index"], out["col"], out["row"] = chain_id, index, x1, y1
    for name in ("col2", "row2", "h", "rho"):
        out[name] = np.nan
    if n == 0:
        return out
    g1x, g1y, _ = gradients(ref, GRADIENT_SIGMA)
    g2x, g2y, _ = gradients(search, GRADIENT_SIGMA)
    grads = kernels.Gradients(*(np.ascontiguousarray(g, np.float32) for g in (g1x, g1y, g2x, g2y)))
    criteria = kernels.EdgelCriteria(
        window // 2,
        RHO_FLOOR,
        math.cos(math.radians(MAX_ANGLE)),
        DIR_WEIGHT,
        math.sin(math.radians(MIN_CROSSING)),
    )
    cand_d = np.full((n, CANDIDATES), np.nan)
    cand = {k: np.full((n, CANDIDATES), np.nan) for k in ("col2", "row2", "h", "rho", "cost")}
    ncand = np.zeros(n, np.int64)
    for b in range(0, n, BLOCK):
        s = slice(b, min(b + BLOCK, n))
        px, py, length = _paths(predict, x1[s], y1[s], lo[s], hi[s])
        aff = _affine(predict, x1[s], y1[s], 0.5 * (lo[s] + hi[s]))
        k = s.stop - s.start
        t, rho, cost = (np.full((k, CANDIDATES), np.nan) for _ in range(3))
        nc = np.zeros(k, np.int64)
        kernels.edgel_candidates(
            ref, search, grads, x1[s], y1[s], px, py, aff, criteria, kernels.Ranked(t, rho, cost, nc)
        )
        m = px.shape[1]
        valid = np.arange(CANDIDATES)[None, :] < nc[:, None]
        tt = np.where(valid, t, 0.0)
        j0 = np.minimum(tt.astype(int), m - 2)
        f = tt - j0
        rows = np.arange(k)[:, None]
        col2 = px[rows, j0] * (1 - f) + px[rows, j0 + 1] * f
        row2 = py[rows, j0] * (1 - f) + py[rows, j0 + 1] * f
        frac = tt / (m - 1)
        cand["col2"][s] = np.where(valid, col2, np.nan)
        cand["row2"][s] = np.where(valid, row2, np.nan)
        cand["h"][s] = np.where(valid, lo[s, None] + (hi - lo)[s, None] * frac, np.nan)
        cand["rho"][s], cand["cost"][s] = rho, cost
        cand_d[s] = np.where(valid, frac * length[:, None], np.nan)
        ncand[s] = nc
    starts = np.flatnonzero(np.r_[True, chain_id[1:] != chain_id[:-1], True]).astype(np.int64)
    choice = np.full(n, -1, np.int64)
    if figural:
        kernels.figural_dp(
            starts,
            index.astype(np.int64),
            float(step),
            ncand,
            cand_d,
            cand["cost"],
            JUMP_COST,
            JUMP_TOL,
            SKIP_COST,
            MAX_SKIP,
            choice,
        )
    else:
        choice[ncand > 0] = 0
    shown = np.where(choice >= 0, choice, 0)
    has = ncand > 0
    r = np.arange(n)
    for name in ("col2", "row2", "h", "rho"):
        out[name][has] = cand[name][r, shown][has]
    ok = (choice >= 0) & (out["rho"] >= rho_min)
    if figural:
        ok &= _supported(chain_id, index / step, np.where(choice >= 0, cand_d[r, shown], np.nan))
    out["ok"] = ok
    return out


def _supported(chain_id, position, d):
    """True where d (NaN = not chosen) agrees within CONTINUITY_TOL per step with the previous or
    the next chosen edgel of the same chain."""
    chosen = np.flatnonzero(np.isfinite(d))
    ok = np.zeros(d.size, bool)
    if chosen.size < 2:
        return ok
    c, p, v = chain_id[chosen], position[chosen], d[chosen]
    same = c[1:] == c[:-1]
    agree = same & (np.abs(np.diff(v)) <= CONTINUITY_TOL * np.diff(p))
    ok[chosen[:-1][agree]] = True
    ok[chosen[1:][agree]] = True
    return ok
