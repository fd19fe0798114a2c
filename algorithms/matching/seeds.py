"""Seed points for region growing (Heipke et al. 1992, section 2).

Automatic seeds: interest points (Foerstner) of image 1, each searched in image 2 by normalised
cross-correlation along the path the two sensor models predict over the height range (image 1 ray
at h_min..h_max projected into image 2: a quasi-epipolar segment, widened by a few pixels across
for orientation errors), with the template sampled through the local affine of the models'
Jacobian, so a 5 m HRG template meets a 10 x 5 m HRS image without resampling either image; the
best candidate is refined by least-squares matching and kept if it passes the acceptance criteria.

`seeds_from_points` does the same for given image-1 points (control or tie points), optionally with
image-2 approximations (then the search is a small square around them)."""

import math

import numpy as np

from ..errors import InputError
from ..height_range import HeightRange
from .imagery import as_image
from .interest import best_per_cell, foerstner
from .lsm import match_accepted
from .ncc import ncc_path
from .pair_geometry import ImagePair, local_affine, predict, search_box
from .params import GrowParams
from .records import PAIR_DTYPE

NCC_MIN = 0.7  # correlation a seed's NCC peak must reach before LSM
NCC_MARGIN = 0.05  # the peak must beat the best candidate > 2 px away by this much (uniqueness)
ACROSS = 3  # px of image 2 searched on each side of the predicted path
CELL = 48  # px of image 1: at most one automatic seed per CELL x CELL cell


def match_candidates(windows, models, x1, y1, hr, params, near=None, radius=3.0):
    """NCC along the predicted path (or around given approximations `near` = (x2, y2) within `radius` px), then
    LSM, for image-1 points (x1, y1) (image coordinates) inside window win1 (offset ox1, oy1), searched in win2
    (offset ox2, oy2): `windows` = (win1, ox1, oy1, win2, ox2, oy2) (region_growing.window_pair), `models` =
    (model1, model2). Returns (records, ok mask)."""
    win1, ox1, oy1, win2, ox2, oy2 = windows
    model1, model2 = models
    x2, y2 = (None, None) if near is None else near
    n = len(x1)
    half = params.template // 2
    hmid = 0.5 * (hr[0] + hr[1])
    _, _, a1, a2, a4, a5 = local_affine(model1, model2, x1, y1, hmid)
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
        ncc_path(win1, win2, x1[i] - ox1, y1[i] - oy1, half, cx - ox2, cy - oy2, a1[i], a2[i], a4[i], a5[i], scores)
        if not np.isfinite(scores).any():
            continue
        best = int(np.nanargmax(scores))
        if not scores[best] >= NCC_MIN:
            continue
        far = np.hypot(cx - cx[best], cy - cy[best]) > 2.0
        rival = np.nanmax(scores[far]) if np.any(far & np.isfinite(scores)) else -1.0
        if scores[best] - rival < NCC_MARGIN:
            continue
        bx[i], by[i] = cx[best], cy[best]
    if min(win1.shape) < 4 or min(win2.shape) < 4:  # an image sliver: nothing can match (match_points needs 4 x 4)
        bx[:] = np.nan
        win1 = win2 = np.zeros((4, 4), np.float32)
    rec, ok = match_accepted(
        win1, win2, x1 - ox1, y1 - oy1, bx - ox2, by - oy2, affine=np.column_stack([a1, a2, a4, a5]), params=params
    )
    rec["x1"], rec["y1"] = x1, y1
    rec["x2"] += ox2
    rec["y2"] += oy2
    return rec, ok


def window_pair(image1, image2, model1, model2, box1, hr, margin2):
    """Windows of image 1 (box1 = x0, y0, x1, y1 in px) and of image 2 (pair_geometry.search_box of
    box1 with margin2 px). Returns (win1, ox1, oy1, win2, ox2, oy2); win2 is empty where the prediction
    misses image 2."""
    x0, y0, xe, ye = box1
    win1, ox1, oy1 = image1.read(x0, y0, xe - x0, ye - y0)
    box2 = search_box(model1, model2, box1, hr, margin2)
    if box2 is None:
        return win1, ox1, oy1, np.zeros((0, 0), np.float32), 0, 0
    xa, ya = int(math.floor(box2[0])), int(math.floor(box2[1]))
    xb, yb = int(math.ceil(box2[2])), int(math.ceil(box2[3]))
    win2, ox2, oy2 = image2.read(xa, ya, xb - xa, yb - ya)
    return win1, ox1, oy1, win2, ox2, oy2


def search_margin(model1, model2, params, hr, x1, y1):
    """Image-2 margin (px) around a predicted footprint: the template through the affine, the
    across-path search, the allowed shift and a safety of 4 px."""
    _, _, a1, a2, a4, a5 = local_affine(
        model1, model2, np.atleast_1d(float(x1)), np.atleast_1d(float(y1)), 0.5 * (hr[0] + hr[1])
    )
    scale = np.nanmax(np.abs([a1, a2, a4, a5])) * 2 if np.all(np.isfinite([a1, a2, a4, a5])) else 2.0
    return (params.widest // 2 + 2) * scale + ACROSS + params.max_shift + 4


def seed_window(params):
    """The Foerstner window automatic seeds use: a third of the template, at least 5 px."""
    return 2 * max(2, (params.template // 2) // 3) + 1


def seed_operator(win1, params):
    """The Foerstner operator's (w, q) images of an image-1 window (interest.foerstner) with seed_window."""
    return foerstner(win1, seed_window(params))


def automatic_seeds(
    pair: ImagePair,
    params=None,
    height_range=None,
    box=None,
    windows=None,
    cell=CELL,
    keep=None,
    operator=None,
):
    """Automatic seeds in image 1's `box` (x0, y0, x1, y1; default the whole image): Foerstner
    points (one per `cell` x `cell` px, interest.py), NCC along the predicted path, LSM; returns
    the accepted PAIR_DTYPE records (seed = -1).
    `windows`: the (win1, ox1, oy1, win2, ox2, oy2) already read for the box (region growing);
    `keep`: a function of image-1 positions (x1, y1) -> mask of the points worth matching;
    `operator`: seed_operator of win1, if already computed."""
    image1, image2, model1, model2 = pair
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    hr = HeightRange.resolve(height_range, model1).bounds
    cols, rows = image1.size
    half = params.template // 2
    if box is None:
        box = (0, 0, cols, rows)
    if windows is None:
        cx, cy = 0.5 * (box[0] + box[2]), 0.5 * (box[1] + box[3])
        windows = window_pair(
            image1, image2, model1, model2, box, hr, search_margin(model1, model2, params, hr, cx, cy)
        )
    win1, ox1, oy1, win2, ox2, oy2 = windows
    if win1.size == 0 or win2.size == 0 or min(win1.shape) < seed_window(params) + 2:  # a sliver: no operator
        return np.zeros(0, PAIR_DTYPE)
    w, q = seed_operator(win1, params) if operator is None else operator
    px, py, _ = best_per_cell(w, q, patch=cell, border=half + 2)
    if len(px) == 0:
        return np.zeros(0, PAIR_DTYPE)
    x1 = px + ox1
    y1 = py + oy1
    inside = (x1 >= box[0]) & (x1 < box[2]) & (y1 >= box[1]) & (y1 < box[3])
    if keep is not None:
        inside &= keep(x1, y1)
    x1, y1 = x1[inside], y1[inside]
    rec, ok = match_candidates(windows, (model1, model2), x1, y1, hr, params)
    return rec[ok]


def seeds_from_points(pair: ImagePair, x1, y1, params=None, height_range=None, x2=None, y2=None, radius=3.0):
    """Seeds at given image-1 points (control or tie points): NCC along the predicted path (or
    within `radius` px of given image-2 approximations x2, y2), then LSM. Returns (PAIR_DTYPE
    records for all points, ok mask of those passing the acceptance criteria)."""
    image1, image2, model1, model2 = pair
    params = (params or GrowParams()).check()
    image1, image2 = as_image(image1), as_image(image2)
    hr = HeightRange.resolve(height_range, model1).bounds
    x1 = np.atleast_1d(np.asarray(x1, float))
    y1 = np.atleast_1d(np.asarray(y1, float))
    if x1.shape != y1.shape:
        raise InputError("x1 and y1 must have the same length")
    recs = np.zeros(len(x1), PAIR_DTYPE)
    recs["x1"], recs["y1"] = x1, y1
    recs["x2"] = recs["y2"] = np.nan
    recs["seed"] = -1
    ok = np.zeros(len(x1), bool)
    pad = params.widest // 2 + 3
    for i in range(len(x1)):  # one small window pair per point: memory stays bounded
        box = (int(x1[i]) - pad, int(y1[i]) - pad, int(x1[i]) + pad + 1, int(y1[i]) + pad + 1)
        margin = search_margin(model1, model2, params, hr, x1[i], y1[i]) + (radius if x2 is not None else 0)
        if x2 is not None:
            win1, ox1, oy1 = image1.read(*box[:2], box[2] - box[0], box[3] - box[1])
            m = int(math.ceil(margin))
            win2, ox2, oy2 = (
                image2.read(int(x2[i]) - m, int(y2[i]) - m, 2 * m + 1, 2 * m + 1)
                if np.isfinite(x2[i]) and np.isfinite(y2[i])
                else (np.zeros((0, 0), np.float32), 0, 0)
            )
        else:
            win1, ox1, oy1, win2, ox2, oy2 = window_pair(image1, image2, model1, model2, box, hr, margin)
        if win1.size == 0 or win2.size == 0:
            continue
        near = None if x2 is None else (np.asarray(x2, float)[i : i + 1], np.asarray(y2, float)[i : i + 1])
        windows = (win1, ox1, oy1, win2, ox2, oy2)
        r, k = match_candidates(windows, (model1, model2), x1[i : i + 1], y1[i : i + 1], hr, params, near, radius)
        recs[i] = r[0]
        ok[i] = k[0]
    return recs, ok
