"""Numba kernel of the coarse-to-fine matcher's candidates (coarse_to_fine_level.candidates; Zhang &
Gruen): for every point at once (prange), NCC of its template along its sampled
quasi-epipolar path (ncc.ncc_path), the across-maximum profile, its local maxima and their
parabola refinement in height and across the path."""

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from .ncc import ncc_path


class Paths(NamedTuple):
    """Sampled quasi-epipolar paths: image-2 positions cx, cy ((k, na) per point: k heights, na samples across)
    and the heights (k,) per point; arrays over the points, or one point's."""

    cx: np.ndarray
    cy: np.ndarray
    heights: np.ndarray


class Affines(NamedTuple):
    """The templates' affine image 1 -> image 2 (a1, a2, a4, a5): arrays over the points, or one point's floats."""

    a1: np.ndarray
    a2: np.ndarray
    a4: np.ndarray
    a5: np.ndarray


class Found(NamedTuple):
    """The candidates, best first, NaN-padded: heights h, NCC rho and image-2 positions x, y ((C,) per point, or
    (n, C) over the points)."""

    h: np.ndarray
    rho: np.ndarray
    x: np.ndarray
    y: np.ndarray


@njit(cache=True, nogil=True)
def _parabola(m, c, p):
    """Sub-sample offset of a parabola's vertex through (-1, m), (0, c), (1, p), in [-0.5, 0.5]."""
    d = m - 2 * c + p
    if d < 0:
        return min(max(0.5 * (m - p) / d, -0.5), 0.5)
    return 0.0


@njit(cache=True, nogil=True)
def _bilinear_at(arr, lo, w, qlo, qhi, wa):
    """arr (k, na) interpolated at path sample lo + w, across sample qlo + wa (qhi = qlo + 1 or qlo)."""
    lo_side = (1 - w) * arr[lo, qlo] + w * arr[lo + 1, qlo]
    hi_side = (1 - w) * arr[lo, qhi] + w * arr[lo + 1, qhi]
    return (1 - wa) * lo_side + wa * hi_side


@njit(cache=True, nogil=True)
def _point(img1, img2, x, y, half, path, affine, rho_min, found):
    """Candidates of one point (coarse_to_fine_level.candidates): its Paths `path` (cx, cy (k, na), heights (k,)),
    its Affines `affine` (floats); fills `found` (Found of (C,) arrays) best first and returns `second` (NaN if
    none)."""
    cx, cy, heights = path
    a1, a2, a4, a5 = affine
    out_h, out_rho, out_x, out_y = found
    k, na = cx.shape
    scores = np.empty(k * na)
    ncc_path(img1, img2, x, y, half, cx.ravel(), cy.ravel(), a1, a2, a4, a5, scores)
    r = np.empty((k, na))
    anyfinite = False
    for j in range(k):
        for q in range(na):
            s = scores[j * na + q]
            if math.isfinite(s):
                r[j, q] = s
                anyfinite = True
            else:
                r[j, q] = -2.0
    if not anyfinite:
        return np.nan
    best_a = np.empty(k, np.int64)
    prof = np.empty(k)
    for j in range(k):
        b = 0
        for q in range(1, na):
            if r[j, q] > r[j, b]:
                b = q
        best_a[j] = b
        prof[j] = r[j, b]
    npk = 0
    peaks = np.empty(k, np.int64)
    for j in range(k):
        left = prof[j - 1] if j > 0 else -3.0
        right = prof[j + 1] if j < k - 1 else -3.0
        if prof[j] >= left and prof[j] > right and prof[j] > -1.0:
            peaks[npk] = j
            npk += 1
    if npk == 0:
        return np.nan
    peaks = peaks[:npk]
    peaks = peaks[np.argsort(-prof[peaks], kind="mergesort")]
    second = prof[peaks[1]] if npk > 1 else np.nan
    c = 0
    for p in peaks:
        if prof[p] <= rho_min or c >= out_h.shape[0]:
            break
        dk = _parabola(prof[p - 1], prof[p], prof[p + 1]) if 0 < p < k - 1 else 0.0
        q = best_a[p]
        da = _parabola(r[p, q - 1], r[p, q], r[p, q + 1]) if 0 < q < na - 1 else 0.0
        pk = min(max(p + dk, 0.0), k - 1.0)
        lo = int(min(math.floor(pk), k - 2))
        w = pk - lo
        qa = min(max(q + da, 0.0), na - 1.0)
        qlo = int(min(math.floor(qa), na - 2)) if na > 1 else 0
        wa = qa - qlo if na > 1 else 0.0
        qhi = min(qlo + 1, na - 1)
        out_h[c] = (1 - w) * heights[lo] + w * heights[lo + 1]
        out_rho[c] = prof[p]
        out_x[c] = _bilinear_at(cx, lo, w, qlo, qhi, wa)
        out_y[c] = _bilinear_at(cy, lo, w, qlo, qhi, wa)
        c += 1
    return second


@njit(cache=True, nogil=True, parallel=True)
def path_candidates(img1, img2, x, y, half, paths, affines, rho_min, found, second):
    """Candidates of all points (coarse_to_fine_level.candidates): x, y, half, rho_min (n,), `paths` (Paths: cx,
    cy (n, k, na), heights (n, k)), `affines` (Affines of (n,) arrays); `found` (Found of (n, C) arrays) and second
    (n,) NaN-filled. Points with a non-finite affine or path position (cx) are skipped."""
    a1, a2, a4, a5 = affines
    for i in prange(x.shape[0]):
        if not (math.isfinite(a1[i]) and math.isfinite(a2[i]) and math.isfinite(a4[i]) and math.isfinite(a5[i])):
            continue
        if not np.isfinite(paths.cx[i]).all():
            continue
        path = Paths(paths.cx[i], paths.cy[i], paths.heights[i])
        mine = Found(found.h[i], found.rho[i], found.x[i], found.y[i])
        second[i] = _point(img1, img2, x[i], y[i], half[i], path, Affines(a1[i], a2[i], a4[i], a5[i]), rho_min[i], mine)
