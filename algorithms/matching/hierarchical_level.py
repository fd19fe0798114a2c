"""One pyramid level of the coarse-to-fine matcher (paper Z, methods.md section 6): level
geometry, the window choice per point and the candidates of geometrically constrained
cross-correlation along the quasi-epipolar path.

Level geometry: level L of a factor-f pyramid has pixels of s = f^L full-resolution pixels
whose edges align (GDAL coordinates: level position (x, y) is full position (s x, s y));
`LevelModel` wraps a sensor model accordingly.

Window choice (Kanade & Okutomi 1994, by the expected error instead of their full adaptive
search; Z section 3.2): a w x w window has the expected shift error
    e^2 = sigma_n^2 2 / sum g^2  +  a mean|xi|
(sigma_n the image noise, g the grey-level gradients in the window: the noise term; the second
the disparity variation inside the window, K-O's model of a disparity that departs from the
centre's with variance a |xi| at distance xi, taken as systematic (terrain shape does not
average out over the window as noise does); a from the previous level's TIN: rough_px^2 /
spacing, the TIN's terrain roughness in px of parallax at its vertex spacing (hierarchical.py,
step 2). Each point takes the smallest of the given sizes whose e reaches `target` px, else the
one with the smallest e: weak texture on flat ground gets large windows, textured areas and rough
terrain (steps, canopy) small ones. The NCC threshold drops likewise with the roughness
(rho_thresholds): larger in flat areas, smaller in rough terrain (Z section 3.2).

Candidates: the reference ray of a point is cut by the height interval [h_lo, h_hi]; its
projection into the search image (quasi-epipolar path) is sampled every <= PATH_STEP px (each
point at its own spacing, the counts rounded up to multiples of COUNT_BUCKET), widened by
`across` px on each side for orientation errors, and the template (shaped by the models' local
affine) is correlated at every sample (ncc.ncc_path), all points in one numba kernel
(hierarchical_kernels.path_candidates). Local maxima along the path of the
across-maximum profile above rho_min are candidates (at most `max_candidates`, best first),
refined by a parabola in height and across the path; each carries its height, rho and image
position. `second` is the best local maximum besides the first (for the peak ratio)."""
import math

import numpy as np

from ..stats import NMAD_SCALE
from .hierarchical_kernels import path_candidates
from .seeds import local_affine, predict

#: largest spacing (px) of the samples along a path
PATH_STEP = 0.5
#: sample counts are rounded up to a multiple of this, so the points run in a few equal-count batches
COUNT_BUCKET = 8


class ShiftedModel:
    """A sensor model whose image positions are moved by (dx, dy) full px, (col', row') = M (col,
    row) + (dx, dy) with M = `linear` (default the identity): the bias compensation of an
    orientation error (hierarchical.estimate_shift's shifts, orientation_bias.affine_bias's
    affine maps), or the model of a window of the image (dx, dy = minus its top-left corner,
    `size` its size: the tiles of hierarchical.py)."""

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
        for key in [k for k in part if k.startswith("d_")]:     # d(col, row)/d(...): (..., 2, k), times M
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
        spread = np.hypot(k[:, None], k[None, :]).mean()                  # mean |xi|
        with np.errstate(divide="ignore"):
            error = np.sqrt(noise ** 2 * 2.0 / energy + rate * spread)
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


def candidates(img1, img2, model1, model2, x, y, h_lo, h_hi, half, across, rho_min, max_candidates):
    """Candidates of points (x, y) of img1 in img2 (module docstring); level models and px. Each
    point's path is sampled at its own spacing (sample_counts), in batches of equal count.
    rho_min: (n,) NCC thresholds.
    Returns dict of (n, C) arrays h, rho, x, y (NaN padded, best first) and (n,) `second`."""
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
        path_candidates(img1, img2, vec[0], vec[1], np.ascontiguousarray(half[sel]), np.ascontiguousarray(cx),
                        np.ascontiguousarray(cy), *vec[2:], np.ascontiguousarray(heights),
                        np.ascontiguousarray(rho_min[sel]), part["h"], part["rho"], part["x"], part["y"],
                        part["second"])
        for key, value in part.items():
            out[key][sel] = value
    return out


def back_match(img1, img2, model1, model2, x, y, x2, y2, h_lo, h_hi, half, across):
    """Back-matching: the template of img2 at (x2, y2) searched in img1 along its own path over
    the same heights; returns the distance (level px) of the best img1 position from (x, y)
    (inf where nothing correlates)."""
    back = candidates(img2, img1, model2, model1, x2, y2, h_lo, h_hi, half, across, np.full(len(x2), -1.0), 1)
    with np.errstate(invalid="ignore"):
        d = np.hypot(back["x"][:, 0] - x, back["y"][:, 0] - y)
    return np.where(np.isfinite(d), d, np.inf)
