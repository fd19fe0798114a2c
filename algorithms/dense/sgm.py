"""Dense disparity of an epipolar pair: census cost, semi-global aggregation, winner-takes-all with a
sub-pixel V fit, and the left-right consistency check.

Model (Hirschmuller 2008; Zabih & Woodfill 1994 for the census):
- census: each pixel's code has one bit per neighbour of a (2 r + 1)^2 window, set where the neighbour
  is darker than the centre; a window with a NaN (nodata, outside the image) gives no code, nor does one
  whose grey values span no more than `min_contrast` (a flat window's code says nothing);
- cost C(p, d) = Hamming distance between the codes of image-1 pixel p = (u, v) and image-2 pixel
  (u + d, v), d = d_min ... d_max (disparity u2 - u1, as pandora's I1(u, v) = I2(u + d, v)); a pair with
  no code costs `invalid` = C_max + P2 + 1, above any aggregated path cost, so that the aggregation
  skips it (libsgm's rule);
- aggregation S(p, d) = sum over 8 directions r of
      L_r(p, d) = C(p, d) + min(L_r(p - r, d), L_r(p - r, d +- 1) + P1, min_k L_r(p - r, k) + P2)
                  - min_k L_r(p - r, k),
  by CNES libsgm (c_libsgm.sgm_api);
- disparity: the minimum of S over d, refined by the V fit of its two neighbours,
      delta = (S(d - 1) - S(d + 1)) / (2 max(S(d - 1) - S(d), S(d + 1) - S(d))),
  none at the range's ends (the true minimum may lie outside); none where S is the same for every d (a
  flat, textureless neighbourhood: nothing to choose);
- left-right check: image 2's disparity from the same S along its diagonal (Hirschmuller 2008, 3.4),
  D2(u2) = argmin_d S(u2 - d, d); p keeps D1(p) where |D1(p) - D2(round(u + D1(p)))| <= `lr_tolerance`
  px (occlusions and mismatches fail it);
- scored candidates: where image 2 has no code at some candidate (u + d, v) of p (nodata or saturated pixels
  within the census window, image 2's edge, a flat window), p's conjugate may be the candidate that cannot be
  scored, and the minimum over the others is then a mismatch that the aggregation makes as smooth as its
  neighbours and the left-right check does not catch (tens of pixels off beside a nodata edge). So p keeps
  D1(p) where every candidate d_min ... d_max has a code, and otherwise only where its own surface bounds it:
  with [lo, hi] the range of the kept disparities within LOCAL_RADIUS px, D1(p) lies in
  [lo - LOCAL_SLACK, hi + LOCAL_SLACK] and every candidate in it has a code. A pixel kept so bounds its own
  neighbours in turn: the kept set grows outwards from the complete pixels until none is added
  (`scored_disparities`). Beside a
  masked area of image 2 this drops a margin of the local relief plus LOCAL_SLACK px around its conjugates,
  not the whole disparity range; where the surface jumps by more than LOCAL_SLACK px within LOCAL_RADIUS px
  (a cliff, a building's edge), a pixel may keep the disparity of its neighbours' surface, as the aggregation
  gives anywhere.

Census and cost are numba kernels of the whole epipolar tile; P1 = 8 and P2 = 32 for a 5 x 5 census
(pandora's defaults for it). Memory: rows x cols x (d_max - d_min + 1) float32 twice (cost and
aggregated volume): the tile and its disparity range set it.

Reference: H. Hirschmuller, "Stereo processing by semiglobal matching and mutual information", IEEE
PAMI 30(2), 2008; R. Zabih, J. Woodfill, "Non-parametric local transforms for computing visual
correspondence", ECCV 1994."""

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import ndimage

#: px around a pixel whose kept disparities bound its own, and the px of disparity allowed beyond their range
#: (module docstring, scored candidates: up to 1 px of disparity change per px, e.g. a 45 degree slope at B/H 1)
LOCAL_RADIUS, LOCAL_SLACK = 3, 3.0
DIRECTIONS = np.array([[0, 1], [1, 0], [1, 1], [1, -1], [0, -1], [-1, 0], [-1, -1], [-1, 1]], dtype=np.int32)


@dataclass(frozen=True)
class SgmParams:
    """census_radius: r of the (2 r + 1)^2 census window; p1, p2: SGM penalties for a disparity change of
    1 and of more; lr_tolerance: px of left-right disagreement kept; min_contrast: grey values a census
    window must span (more than) to give a code."""

    census_radius: int = 2
    p1: float = 8.0
    p2: float = 32.0
    lr_tolerance: float = 1.0
    min_contrast: float = 0.0


@njit(cache=True, nogil=True)
def census_kernel(img, r, min_contrast, codes, valid):
    """codes[i, j]: bit k set where neighbour k of the (2r+1)^2 window (row-major, centre skipped) is
    darker than the centre; valid[i, j]: the window lies inside img, holds no NaN and spans more than
    min_contrast."""
    rows, cols = img.shape
    for i in range(rows):
        for j in range(cols):
            codes[i, j] = 0
            valid[i, j] = False
            if i < r or j < r or i + r >= rows or j + r >= cols:
                continue
            c = img[i, j]
            if not c == c:
                continue
            code = np.uint64(0)
            ok = True
            lo = c
            hi = c
            for a in range(-r, r + 1):
                for b in range(-r, r + 1):
                    if a == 0 and b == 0:
                        continue
                    g = img[i + a, j + b]
                    if not g == g:
                        ok = False
                    lo = min(lo, g)
                    hi = max(hi, g)
                    code = code << np.uint64(1)
                    if g < c:
                        code = code | np.uint64(1)
            if ok and hi - lo > min_contrast:
                codes[i, j] = code
                valid[i, j] = True


@njit(cache=True, nogil=True)
def _popcount(x):
    n = 0
    while x:
        x &= x - np.uint64(1)
        n += 1
    return n


@njit(cache=True, nogil=True)
def cost_kernel(c1, v1, c2, v2, d_min, invalid, cv):
    """cv[i, j, k] = Hamming(c1[i, j], c2[i, j + d_min + k]); `invalid` where either has no code."""
    rows, cols, nd = cv.shape
    cols2 = c2.shape[1]
    for i in range(rows):
        for j in range(cols):
            for k in range(nd):
                j2 = j + d_min + k
                if v1[i, j] and 0 <= j2 < cols2 and v2[i, j2]:
                    cv[i, j, k] = _popcount(c1[i, j] ^ c2[i, j2])
                else:
                    cv[i, j, k] = invalid


@njit(cache=True, nogil=True)
def winner_kernel(s, d_min, limit, disp, cost):
    """disp[i, j]: d_min + argmin_k s[i, j, k] with the V fit (no fit at the range's ends), NaN where
    every s is >= limit (no valid cost) or all are equal (no texture, nothing to choose); cost[i, j]
    its minimum."""
    rows, cols, nd = s.shape
    for i in range(rows):
        for j in range(cols):
            best = 0
            top = s[i, j, 0]
            for k in range(1, nd):
                if s[i, j, k] < s[i, j, best]:
                    best = k
                top = max(top, s[i, j, k])
            c0 = s[i, j, best]
            cost[i, j] = c0
            if not c0 < limit or not c0 < top:
                disp[i, j] = np.nan
                continue
            delta = 0.0
            if 0 < best < nd - 1:
                cm, cp = s[i, j, best - 1], s[i, j, best + 1]
                if cm < limit and cp < limit:
                    slope = max(cm - c0, cp - c0)
                    if slope > 0:
                        delta = (cm - cp) / (2.0 * slope)
            disp[i, j] = d_min + best + delta


@njit(cache=True, nogil=True)
def right_kernel(s, d_min, limit, cols2, disp2):
    """disp2[i, j2]: image 2's integer disparity d = argmin over k of s[i, j2 - d, k] (d = d_min + k), the
    diagonal of the same volume; NaN where no valid cost."""
    rows, cols, nd = s.shape
    for i in range(rows):
        for j2 in range(cols2):
            best = -1
            bc = limit
            for k in range(nd):
                j = j2 - (d_min + k)
                if 0 <= j < cols and s[i, j, k] < bc:
                    bc = s[i, j, k]
                    best = k
            disp2[i, j2] = np.nan if best < 0 else d_min + best


@njit(cache=True, nogil=True)
def lr_check_kernel(disp, disp2, tolerance):
    """disp set to NaN where image 2's disparity at u + disp differs by more than `tolerance`."""
    rows, cols = disp.shape
    cols2 = disp2.shape[1]
    for i in range(rows):
        for j in range(cols):
            d = disp[i, j]
            if not d == d:
                continue
            j2 = int(np.floor(j + d + 0.5))
            if j2 < 0 or j2 >= cols2 or not abs(disp2[i, j2] - d) <= tolerance:
                disp[i, j] = np.nan


def _missing_codes(v2):
    """missing[i, m]: the image-2 pixels of row i without a code before column m."""
    missing = np.zeros((v2.shape[0], v2.shape[1] + 1), np.int64)
    missing[:, 1:] = np.cumsum(~v2, axis=1)
    return missing


def _scored(missing, i, j, lo, hi):
    """Per image-1 pixel (i, j): candidates (i, j + lo ... j + hi) all inside image 2 and with a code."""
    a, b = j + lo, j + hi + 1
    cols2 = missing.shape[1] - 1
    inside = (a >= 0) & (b <= cols2)
    a, b = np.clip(a, 0, cols2), np.clip(b, 0, cols2)
    return inside & (missing[i, b] - missing[i, a] == 0)


def scored_disparities(disp: np.ndarray, v1: np.ndarray, v2: np.ndarray, d_min: int, d_max: int) -> np.ndarray:
    """`disp` (image 1's disparities over d_min ... d_max, NaN: none) with NaN where a pixel's conjugate may be a
    candidate without a code (module docstring, scored candidates); v1, v2: the census codes' masks."""
    missing = _missing_codes(v2)
    i, j = np.indices(disp.shape)
    trusted = np.isfinite(disp) & v1 & _scored(missing, i, j, d_min, d_max)
    pending = np.isfinite(disp) & ~trusted
    size = 2 * LOCAL_RADIUS + 1
    while pending.any():
        lo = ndimage.minimum_filter(np.where(trusted, disp, np.inf), size, mode="constant", cval=np.inf)
        hi = ndimage.maximum_filter(np.where(trusted, disp, -np.inf), size, mode="constant", cval=-np.inf)
        with np.errstate(invalid="ignore"):
            near = pending & (disp >= lo - LOCAL_SLACK) & (disp <= hi + LOCAL_SLACK)
        k = np.nonzero(near)
        a = np.clip(np.floor(lo[k] - LOCAL_SLACK), d_min, d_max).astype(np.int64)
        b = np.clip(np.ceil(hi[k] + LOCAL_SLACK), d_min, d_max).astype(np.int64)
        ok = _scored(missing, k[0], k[1], a, b)
        if not ok.any():
            break
        trusted[k[0][ok], k[1][ok]] = True
        pending[k[0][ok], k[1][ok]] = False
    return np.where(trusted, disp, np.float32(np.nan)).astype(np.float32)


def census(img, radius, min_contrast=0.0):
    """(codes uint64, valid bool) of a float image (NaN: nodata)."""
    img = np.ascontiguousarray(img, dtype=np.float32)
    codes = np.zeros(img.shape, np.uint64)
    valid = np.zeros(img.shape, np.bool_)
    census_kernel(img, int(radius), float(min_contrast), codes, valid)
    return codes, valid


def disparity(epi1, epi2, d_range, params=SgmParams()):
    """The dense disparity (float32, epi1's shape, u2 - u1 in epipolar px, NaN where unmatched or
    inconsistent) of epipolar images epi1, epi2 (same rows) over the integer range d_range = (d_min, d_max)."""
    import c_libsgm

    if epi1.shape[0] != epi2.shape[0]:
        raise ValueError(f"epipolar images must have the same rows, got {epi1.shape} and {epi2.shape}")
    d_min, d_max = int(np.floor(d_range[0])), int(np.ceil(d_range[1]))
    nd = d_max - d_min + 1
    r = int(params.census_radius)
    c_max = (2 * r + 1) ** 2 - 1
    invalid = float(c_max + params.p2 + 1)
    c1, v1 = census(epi1, r, params.min_contrast)
    c2, v2 = census(epi2, r, params.min_contrast)
    cv = np.empty(epi1.shape + (nd,), np.float32)
    cost_kernel(c1, v1, c2, v2, d_min, np.float32(invalid), cv)
    shape = epi1.shape + (len(DIRECTIONS),)
    p1 = np.full(shape, params.p1, np.float32)
    p2 = np.full(shape, params.p2, np.float32)
    s = c_libsgm.sgm_api(cv, p1, p2, DIRECTIONS, np.float32(invalid), np.ones(epi1.shape, np.float32), False, False)[
        "cv"
    ]
    del cv, p1, p2
    # a valid path never sums to more than 8 (C_max + P2) (libsgm's bound, per direction)
    limit = np.float32(len(DIRECTIONS) * (c_max + params.p2))
    disp = np.empty(epi1.shape, np.float32)
    cost = np.empty(epi1.shape, np.float32)
    winner_kernel(s, d_min, limit, disp, cost)
    disp2 = np.empty(epi2.shape, np.float32)
    right_kernel(s, d_min, limit, epi2.shape[1], disp2)
    lr_check_kernel(disp, disp2, np.float32(params.lr_tolerance))
    return scored_disparities(disp, v1, v2, d_min, d_max)
