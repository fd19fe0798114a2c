"""Seed points for region growing (methods.md section 3; H section 2).

Automatic seeds: interest points (Foerstner) of image 1, each searched in image 2 by normalised
cross-correlation along the path the two sensor models predict over the height range (image 1 ray
at h_min..h_max projected into image 2: a quasi-epipolar segment, widened by a few pixels across
for orientation errors), with the template sampled through the local affine of the models'
Jacobian, so a 5 m HRG template meets a 10 x 5 m HRS image without resampling either image; the
best candidate is refined by least-squares matching and kept if it passes the acceptance criteria.

`seeds_from_points` does the same for given image-1 points (control or tie points), optionally with
image-2 approximations (then the search is a small square around them).

Geometry helpers shared with region_growing: `resolve_height_range`, `predict`, `local_affine`."""
import math

import numpy as np
from numba import njit

from ..errors import InputError
from .imagery import as_image
from .params import GrowParams
from .records import PAIR_DTYPE

NCC_MIN = 0.7        # correlation a seed's NCC peak must reach before LSM
NCC_MARGIN = 0.05    # the peak must beat the best candidate > 2 px away by this much (uniqueness)
ACROSS = 3           # px of image 2 searched on each side of the predicted path
CELL = 48            # px of image 1: at most one automatic seed per CELL x CELL cell


# --------------------------------------------------------------------------------------------
# geometry

def resolve_height_range(model1, height_range):
    """(h_min, h_max) from a pair, a scalar mean height (-> +-500 m) or the model's own
    `height_range` (RPC validity domain); raises InputError when none is known."""
    if height_range is None:
        hr = getattr(model1, "height_range", None)
        if hr is None:
            raise InputError("the height range of the scene is unknown: give height_range=(h_min, h_max) "
                             "or a mean ellipsoidal height (then +-500 m are searched)")
        height_range = hr
    if np.ndim(height_range) == 0:
        h = float(height_range)
        height_range = (h - 500.0, h + 500.0)
    lo, hi = (float(v) for v in height_range)
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo:
        raise InputError(f"height_range must be (h_min, h_max) with h_min <= h_max, got {height_range}")
    return lo, hi


def predict(model1, model2, x1, y1, h):
    """Image-2 (x2, y2) of image-1 points (x1, y1) at ellipsoidal height(s) h (NaN outside)."""
    x1, y1, h = np.broadcast_arrays(np.asarray(x1, float), np.asarray(y1, float), np.asarray(h, float))
    lon, lat = model1.image_to_ground(x1.ravel().copy(), y1.ravel().copy(), h.ravel().copy())
    x2, y2 = model2.ground_to_image(np.asarray(lon), np.asarray(lat), h.ravel().copy())
    return np.asarray(x2, float).reshape(x1.shape), np.asarray(y2, float).reshape(x1.shape)


def local_affine(model1, model2, x1, y1, h, d=5.0):
    """Image-2 position and the affine (a1, a2, a4, a5) = d(x2, y2)/d(x1, y1) at height h, by
    central differences of `d` px. Returns (x2, y2, a1, a2, a4, a5) arrays."""
    x1 = np.atleast_1d(np.asarray(x1, float))
    y1 = np.atleast_1d(np.asarray(y1, float))
    h = np.broadcast_to(np.asarray(h, float), x1.shape)
    xs = np.concatenate([x1, x1 + d, x1 - d, x1, x1])
    ys = np.concatenate([y1, y1, y1, y1 + d, y1 - d])
    x2, y2 = predict(model1, model2, xs, ys, np.concatenate([h] * 5))
    n = x1.size
    c, px, mx, py, my = (slice(k * n, (k + 1) * n) for k in range(5))
    return (x2[c], y2[c], (x2[px] - x2[mx]) / (2 * d), (x2[py] - x2[my]) / (2 * d),
            (y2[px] - y2[mx]) / (2 * d), (y2[py] - y2[my]) / (2 * d))


# --------------------------------------------------------------------------------------------
# kernels

@njit(cache=True, nogil=True)
def _bilinear(img, x, y):
    """Bilinear value of `img` at image position (x, y) of the array (pixel centres at +0.5);
    NaN outside."""
    u = x - 0.5
    v = y - 0.5
    j = int(math.floor(u))
    i = int(math.floor(v))
    if i < 0 or j < 0 or i + 1 >= img.shape[0] or j + 1 >= img.shape[1]:
        return np.nan
    fu = u - j
    fv = v - i
    return ((1 - fv) * ((1 - fu) * img[i, j] + fu * img[i, j + 1])
            + fv * ((1 - fu) * img[i + 1, j] + fu * img[i + 1, j + 1]))


@njit(cache=True, nogil=True)
def ncc_candidates(img1, img2, x1, y1, a1, a2, a4, a5, cx, cy, half, scores):
    """NCC of the (2 half + 1)^2 template of img1 at (x1 + k, y1 + l) against img2 sampled at
    (cx[c] + a1 k + a2 l, cy[c] + a4 k + a5 l) for every candidate c (array coordinates of
    each image); writes scores (NaN where a window leaves an image or is flat) and returns the
    index of the best candidate (-1 if none)."""
    m = 2 * half + 1
    t = np.empty(m * m)
    n = 0
    for l in range(-half, half + 1):
        for k in range(-half, half + 1):
            t[n] = _bilinear(img1, x1 + k, y1 + l)
            n += 1
    tm = t.mean()
    t -= tm
    tt = (t * t).sum()
    best = -1
    best_score = -2.0
    for c in range(cx.size):
        scores[c] = np.nan
        if not tt > 0:
            continue
        s = 0.0
        s2 = 0.0
        st = 0.0
        n = 0
        bad = False
        for l in range(-half, half + 1):
            for k in range(-half, half + 1):
                g = _bilinear(img2, cx[c] + a1 * k + a2 * l, cy[c] + a4 * k + a5 * l)
                if not math.isfinite(g):
                    bad = True
                    break
                s += g
                s2 += g * g
                st += g * t[n]
                n += 1
            if bad:
                break
        if bad:
            continue
        var = s2 - s * s / n
        if var <= 1e-9 * n:
            continue
        r = st / math.sqrt(var * tt)
        scores[c] = r
        if r > best_score:
            best_score = r
            best = c
    return best


def ncc_reference(img1, img2, x1, y1, a1, a2, a4, a5, cx, cy, half):
    """Plain numpy reference of ncc_candidates (tests)."""
    from scipy.ndimage import map_coordinates
    k, l = np.meshgrid(np.arange(-half, half + 1), np.arange(-half, half + 1))
    t = map_coordinates(img1.astype(float), [y1 + l - 0.5, x1 + k - 0.5], order=1).ravel()
    t = t - t.mean()
    out = np.full(len(cx), np.nan)
    for c in range(len(cx)):
        g = map_coordinates(img2.astype(float), [cy[c] + a4 * k + a5 * l - 0.5, cx[c] + a1 * k + a2 * l - 0.5],
                            order=1).ravel()
        g = g - g.mean()
        out[c] = (g * t).sum() / math.sqrt((g * g).sum() * (t * t).sum())
    return out


# --------------------------------------------------------------------------------------------
# interest points

def interest_points(window, half, cell=CELL, q_min=0.5):
    """Foerstner points of a float32 window: (col, row) array positions (pixel centres) of the
    strongest point (weight w = det N / trace N of the gradient structure tensor over a
    (2 half + 1)^2 window, roundness q = 4 det / trace^2 > q_min) in each cell x cell cell,
    ordered by decreasing w, keeping `half` + 1 px away from the window border."""
    try:  # the project's Foerstner operator, when present
        from . import interest
        fn = getattr(interest, "foerstner_cells", None)
        if fn is not None:
            return fn(window, half=half, cell=cell, q_min=q_min)
    except ImportError:
        pass
    from scipy.ndimage import uniform_filter
    img = np.nan_to_num(window.astype(np.float64), nan=0.0)
    gy, gx = np.gradient(img)
    size = 2 * max(2, half // 3) + 1
    nxx = uniform_filter(gx * gx, size)
    nyy = uniform_filter(gy * gy, size)
    nxy = uniform_filter(gx * gy, size)
    det = nxx * nyy - nxy * nxy
    tr = nxx + nyy
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(tr > 0, det / tr, 0.0)
        q = np.where(tr > 0, 4 * det / (tr * tr), 0.0)
    w[(q < q_min) | ~np.isfinite(window) | (w < 1e-6 * max(float(w.max()), 1e-30))] = 0.0
    border = half + 2
    w[:border, :] = 0
    w[-border:, :] = 0
    w[:, :border] = 0
    w[:, -border:] = 0
    rows, cols = w.shape
    points = []
    for i0 in range(0, rows, cell):
        for j0 in range(0, cols, cell):
            block = w[i0:i0 + cell, j0:j0 + cell]
            if block.size == 0:
                continue
            k = int(np.argmax(block))
            i, j = divmod(k, block.shape[1])
            if block[i, j] > 0:
                points.append((block[i, j], j0 + j + 0.5, i0 + i + 0.5))
    points.sort(key=lambda p: (-p[0], p[2], p[1]))
    if not points:
        return np.zeros((0, 2))
    return np.array([(p[1], p[2]) for p in points])


# --------------------------------------------------------------------------------------------
# matching seeds

def _lsm_many(img1, img2, x1, y1, x2, y2, a, params):
    """LSM of every point (array coordinates of the windows); returns (LSM output rows, status)."""
    from .lsm import LSM_FIELDS, lsm_point
    n = len(x1)
    out = np.full((n, len(LSM_FIELDS)), np.nan)
    status = np.full(n, -1, np.int64)
    half = params.template // 2
    for i in range(n):
        if not (np.isfinite(x2[i]) and np.isfinite(y2[i])):
            continue
        status[i] = lsm_point(img1, img2, float(x1[i]), float(y1[i]), float(x2[i]), float(y2[i]),
                              float(a[0][i]), float(a[1][i]), float(a[2][i]), float(a[3][i]),
                              half, params.max_iterations, params.convergence, out[i])
    return out, status


def passes(out, status, params):
    """Acceptance criteria of lsm.accepted on LSM output rows (status 0 where matched)."""
    from .lsm import accepted
    return accepted(to_records(np.zeros(len(out)), np.zeros(len(out)), out), np.where(status < 0, 1, status),
                    params)


def to_records(x1, y1, out, ox2=0.0, oy2=0.0, seed=None):
    """PAIR_DTYPE records from image-1 positions and LSM output rows (image-2 window offset)."""
    from .lsm import LSM_FIELDS
    rec = np.zeros(len(x1), PAIR_DTYPE)
    rec["x1"], rec["y1"] = x1, y1
    for i, name in enumerate(LSM_FIELDS):
        if name in PAIR_DTYPE.names:
            rec[name] = out[:, i] if PAIR_DTYPE[name].kind == "f" else np.nan_to_num(out[:, i], nan=0.0)
    rec["x2"] += ox2
    rec["y2"] += oy2
    rec["seed"] = -1 if seed is None else seed
    return rec


def match_candidates(win1, ox1, oy1, win2, ox2, oy2, model1, model2, x1, y1, hr, params,
                     x2=None, y2=None, radius=3.0):
    """NCC along the predicted path (or around given approximations x2, y2 within `radius` px),
    then LSM, for image-1 points (x1, y1) (image coordinates) inside window win1 (offset ox1, oy1),
    searched in win2 (offset ox2, oy2). Returns (records, ok mask)."""
    n = len(x1)
    half = params.template // 2
    hmid = 0.5 * (hr[0] + hr[1])
    px, py, a1, a2, a4, a5 = local_affine(model1, model2, x1, y1, hmid)
    if x2 is None:
        xa, ya = predict(model1, model2, x1, y1, np.full(n, hr[0]))
        xb, yb = predict(model1, model2, x1, y1, np.full(n, hr[1]))
    else:
        x2 = np.asarray(x2, float)
        y2 = np.asarray(y2, float)
    bx = np.full(n, np.nan)
    by = np.full(n, np.nan)
    for i in range(n):
        if x2 is None:
            if not np.all(np.isfinite([xa[i], ya[i], xb[i], yb[i]])):
                continue
            dx, dy = xb[i] - xa[i], yb[i] - ya[i]
            length = math.hypot(dx, dy)
            t = np.linspace(0.0, 1.0, max(2, int(math.ceil(length)) + 1))
            ux, uy = (dx / length, dy / length) if length > 1e-9 else (1.0, 0.0)
            off = np.arange(-ACROSS, ACROSS + 1, dtype=float)
            cx = (xa[i] + t[:, None] * dx - uy * off[None, :]).ravel()
            cy = (ya[i] + t[:, None] * dy + ux * off[None, :]).ravel()
        else:
            if not (np.isfinite(x2[i]) and np.isfinite(y2[i])):
                continue
            off = np.arange(-math.ceil(radius), math.ceil(radius) + 1, dtype=float)
            cx = (x2[i] + off[None, :] + 0 * off[:, None]).ravel()
            cy = (y2[i] + off[:, None] + 0 * off[None, :]).ravel()
        scores = np.empty(cx.size)
        best = ncc_candidates(win1, win2, x1[i] - ox1, y1[i] - oy1, a1[i], a2[i], a4[i], a5[i],
                              cx - ox2, cy - oy2, half, scores)
        if best < 0 or not scores[best] >= NCC_MIN:
            continue
        far = np.hypot(cx - cx[best], cy - cy[best]) > 2.0
        rival = np.nanmax(scores[far]) if np.any(far & np.isfinite(scores)) else -1.0
        if scores[best] - rival < NCC_MARGIN:
            continue
        bx[i], by[i] = cx[best], cy[best]
    out, status = _lsm_many(win1, win2, x1 - ox1, y1 - oy1, bx - ox2, by - oy2, (a1, a2, a4, a5), params)
    ok = passes(out, status, params)
    rec = to_records(x1, y1, out, ox2, oy2)
    return rec, ok


def window_pair(image1, image2, model1, model2, box1, hr, margin2):
    """Windows of image 1 (box1 = x0, y0, x1, y1 in px) and of image 2 covering the models'
    prediction of box1 over the height range plus margin2 px. Returns (win1, ox1, oy1, win2, ox2,
    oy2); win2 is empty where the prediction misses image 2."""
    x0, y0, xe, ye = box1
    win1, ox1, oy1 = image1.read(x0, y0, xe - x0, ye - y0)
    gx, gy = np.meshgrid(np.linspace(x0, xe, 5), np.linspace(y0, ye, 5))
    xs, ys = [], []
    for h in np.linspace(hr[0], hr[1], 3):
        px, py = predict(model1, model2, gx.ravel(), gy.ravel(), np.full(gx.size, h))
        xs.append(px)
        ys.append(py)
    xs = np.concatenate(xs)
    ys = np.concatenate(ys)
    good = np.isfinite(xs) & np.isfinite(ys)
    if not good.any():
        return win1, ox1, oy1, np.zeros((0, 0), np.float32), 0, 0
    xa = int(math.floor(xs[good].min() - margin2))
    xb = int(math.ceil(xs[good].max() + margin2))
    ya = int(math.floor(ys[good].min() - margin2))
    yb = int(math.ceil(ys[good].max() + margin2))
    win2, ox2, oy2 = image2.read(xa, ya, xb - xa, yb - ya)
    return win1, ox1, oy1, win2, ox2, oy2


def search_margin(model1, model2, params, hr, x1, y1):
    """Image-2 margin (px) around a predicted footprint: the template through the affine, the
    across-path search, the allowed shift and a safety of 4 px."""
    _, _, a1, a2, a4, a5 = local_affine(model1, model2, np.atleast_1d(float(x1)), np.atleast_1d(float(y1)),
                                        0.5 * (hr[0] + hr[1]))
    scale = np.nanmax(np.abs([a1, a2, a4, a5])) * 2 if np.all(np.isfinite([a1, a2, a4, a5])) else 2.0
    return (params.template // 2 + 2) * scale + ACROSS + params.max_shift + 4


def automatic_seeds(image1, image2, model1, model2, params=None, height_range=None, box=None,
                    feedback=None, windows=None):
    """Automatic seeds in image 1's `box` (x0, y0, x1, y1; default the whole image): Foerstner
    points, NCC along the predicted path, LSM; returns the accepted PAIR_DTYPE records (seed = -1).
    `windows`: the (win1, ox1, oy1, win2, ox2, oy2) already read for the box (region growing)."""
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    hr = resolve_height_range(model1, height_range)
    cols, rows = image1.size
    half = params.template // 2
    if box is None:
        box = (0, 0, cols, rows)
    if windows is None:
        cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        windows = window_pair(image1, image2, model1, model2, box, hr,
                              search_margin(model1, model2, params, hr, cx, cy))
    win1, ox1, oy1, win2, ox2, oy2 = windows
    if win1.size == 0 or win2.size == 0:
        return np.zeros(0, PAIR_DTYPE)
    pts = interest_points(win1, half)
    if len(pts) == 0:
        return np.zeros(0, PAIR_DTYPE)
    x1 = pts[:, 0] + ox1
    y1 = pts[:, 1] + oy1
    inside = (x1 >= box[0]) & (x1 < box[2]) & (y1 >= box[1]) & (y1 < box[3])
    x1, y1 = x1[inside], y1[inside]
    rec, ok = match_candidates(win1, ox1, oy1, win2, ox2, oy2, model1, model2, x1, y1, hr, params)
    return rec[ok]


def seeds_from_points(image1, image2, model1, model2, x1, y1, params=None, height_range=None,
                      x2=None, y2=None, radius=3.0):
    """Seeds at given image-1 points (control or tie points): NCC along the predicted path (or
    within `radius` px of given image-2 approximations x2, y2), then LSM. Returns (PAIR_DTYPE
    records for all points, ok mask of those passing the acceptance criteria)."""
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    hr = resolve_height_range(model1, height_range)
    x1 = np.atleast_1d(np.asarray(x1, float))
    y1 = np.atleast_1d(np.asarray(y1, float))
    if x1.shape != y1.shape:
        raise InputError("x1 and y1 must have the same length")
    recs = np.zeros(len(x1), PAIR_DTYPE)
    recs["x1"], recs["y1"] = x1, y1
    recs["x2"] = recs["y2"] = np.nan
    recs["seed"] = -1
    ok = np.zeros(len(x1), bool)
    half = params.template // 2
    for i in range(len(x1)):   # one small window pair per point: memory stays bounded
        pad = half + 3
        box = (int(x1[i]) - pad, int(y1[i]) - pad, int(x1[i]) + pad + 1, int(y1[i]) + pad + 1)
        margin = search_margin(model1, model2, params, hr, x1[i], y1[i]) + (radius if x2 is not None else 0)
        if x2 is not None:
            win1, ox1, oy1 = image1.read(*box[:2], box[2] - box[0], box[3] - box[1])
            m = int(math.ceil(margin))
            win2, ox2, oy2 = image2.read(int(x2[i]) - m, int(y2[i]) - m, 2 * m + 1, 2 * m + 1) \
                if np.isfinite(x2[i]) and np.isfinite(y2[i]) else (np.zeros((0, 0), np.float32), 0, 0)
        else:
            win1, ox1, oy1, win2, ox2, oy2 = window_pair(image1, image2, model1, model2, box, hr, margin)
        if win1.size == 0 or win2.size == 0:
            continue
        r, k = match_candidates(win1, ox1, oy1, win2, ox2, oy2, model1, model2, x1[i:i + 1], y1[i:i + 1], hr,
                                params, None if x2 is None else np.asarray(x2, float)[i:i + 1],
                                None if y2 is None else np.asarray(y2, float)[i:i + 1], radius)
        recs[i] = r[0]
        ok[i] = k[0]
    return recs, ok
