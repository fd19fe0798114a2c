"""Image preprocessing for the multi-primitive matcher (Zhang and Gruen 2004, section 3.1): edge-preserving smoothing
(Saint-Marc, Chen & Medioni 1991), then the Wallis filter, then an image pyramid reducing the
resolution by a factor 3 per level. Everything works on float32 copies, so 12/16-bit input (uint16)
keeps its full depth (float32 holds every integer up to 2^24 exactly); NaN marks nodata and stays
NaN.

Coordinates are GDAL's (corner (0, 0), array pixel (i, j) centred at (j + 0.5, i + 0.5)). Pixel
(i, j) of pyramid level L is the mean of the factor x factor block of level L - 1 under it, so it
covers full-resolution columns [factor^L j, factor^L (j + 1)) and rows [factor^L i, factor^L (i + 1));
a point (x, y) at full resolution lies at (x, y) / factor^L in level L (to_level / from_level). The
last block of a row or column may be partial (level sizes are ceil(size / factor)): its mean is
over the pixels inside the image."""

import math

import numpy as np
from numba import njit, prange

from ..errors import InputError

#: rows per parallel band of the Wallis kernel (each band re-reads window - 1 rows to start)
_BAND = 256


def _float_image(img):
    """A float32 copy of a 2-D image."""
    a = np.array(img, dtype=np.float32)
    if a.ndim != 2 or a.size == 0:
        raise InputError(f"need a non-empty 2-D image, got an array of shape {a.shape}")
    return a


@njit(cache=True, nogil=True)
def _wallis_band(img, out, first, last, h, shift, mf, sf, c, b):
    """Wallis filter of rows first..last-1 (see wallis); window sums by running column sums (rows
    i - h..i + h) and a running sum along the row; values shifted by `shift` before squaring."""
    rows, cols = img.shape
    s1 = np.zeros(cols)
    s2 = np.zeros(cols)
    sn = np.zeros(cols)
    for i in range(max(0, first - h - 1), min(rows, first + h)):
        for j in range(cols):
            v = img[i, j]
            if not math.isnan(v):
                s1[j] += v - shift
                s2[j] += (v - shift) ** 2
                sn[j] += 1.0
    for i in range(first, last):
        add, sub = i + h, i - h - 1
        for j in range(cols):
            if add < rows and not math.isnan(img[add, j]):
                s1[j] += img[add, j] - shift
                s2[j] += (img[add, j] - shift) ** 2
                sn[j] += 1.0
            if sub >= 0 and not math.isnan(img[sub, j]):
                s1[j] -= img[sub, j] - shift
                s2[j] -= (img[sub, j] - shift) ** 2
                sn[j] -= 1.0
        a1 = a2 = an = 0.0
        for j in range(min(h, cols)):
            a1 += s1[j]
            a2 += s2[j]
            an += sn[j]
        for j in range(cols):
            if j + h < cols:
                a1 += s1[j + h]
                a2 += s2[j + h]
                an += sn[j + h]
            if j - h - 1 >= 0:
                a1 -= s1[j - h - 1]
                a2 -= s2[j - h - 1]
                an -= sn[j - h - 1]
            g = img[i, j]
            if math.isnan(g):
                out[i, j] = np.nan
                continue
            m = a1 / an  # local mean - shift (an >= 1: g itself)
            sw = math.sqrt(max(a2 / an - m * m, 0.0))
            den = c * sw + (1.0 - c) * sf
            r1 = c * sf / den if den > 0 else 0.0
            out[i, j] = (g - shift - m) * r1 + b * mf + (1.0 - b) * (m + shift)


@njit(cache=True, nogil=True, parallel=True)
def _wallis_kernel(img, out, h, shift, mf, sf, c, b):
    """_wallis_band over bands of _BAND rows, in parallel."""
    bands = (img.shape[0] + _BAND - 1) // _BAND
    for k in prange(bands):
        _wallis_band(img, out, k * _BAND, min(img.shape[0], (k + 1) * _BAND), h, shift, mf, sf, c, b)


def wallis(img, window=21, target_mean=127.0, target_std=50.0, contrast=0.8, brightness=0.9):
    """Wallis filter (Zhang and Gruen 2004, section 3.1 names it without an equation; this is the usual form):

        g' = (g - m_w) r1 + r0,   r1 = c s_f / (c s_w + (1 - c) s_f),   r0 = b m_f + (1 - b) m_w

    m_w, s_w: mean and standard deviation (1/n) of the valid pixels of the window x window window
    centred on the pixel (clipped at the image border, NaN excluded); m_f, s_f: target mean and
    std; c: contrast expansion (0 < c <= 1), b: brightness forcing (0 <= b <= 1). A flat window
    (s_w = 0, so g = m_w) gives r0. float32 out, not clipped; NaN stays NaN."""
    a = _float_image(img)
    if window < 3 or window % 2 == 0:
        raise InputError(f"the Wallis window must be an odd number of pixels >= 3, got {window}")
    if not 0.0 < contrast <= 1.0 or not 0.0 <= brightness <= 1.0 or not target_std > 0:
        raise InputError(
            f"Wallis parameters out of range: contrast {contrast} (0 < c <= 1), brightness "
            f"{brightness} (0 <= b <= 1), target std {target_std} (> 0)"
        )
    out = np.empty_like(a)
    sample = a[::8, ::8]
    sample = sample[np.isfinite(sample)]
    shift = float(np.floor(sample.mean())) if sample.size else 0.0  # near the mean; integers stay exact
    _wallis_kernel(
        a, out, window // 2, shift, float(target_mean), float(target_std), float(contrast), float(brightness)
    )
    return out


@njit(cache=True, nogil=True)
def _grad2(img, i, j):
    """|grad|^2 at pixel (i, j) (not NaN) with central differences (I(x+1) - I(x-1)) / 2; a neighbour
    outside the image or NaN is replaced by the pixel itself."""
    rows, cols = img.shape
    v = img[i, j]
    left = img[i, j - 1] if j > 0 else v
    right = img[i, j + 1] if j + 1 < cols else v
    up = img[i - 1, j] if i > 0 else v
    down = img[i + 1, j] if i + 1 < rows else v
    left = v if math.isnan(left) else left
    right = v if math.isnan(right) else right
    up = v if math.isnan(up) else up
    down = v if math.isnan(down) else down
    return 0.25 * ((right - left) ** 2 + (down - up) ** 2)


@njit(cache=True, nogil=True, parallel=True)
def _gradient_squared(img, g2):
    """|grad|^2 of every pixel (_grad2); NaN where the pixel is NaN."""
    for i in prange(img.shape[0]):
        for j in range(img.shape[1]):
            g2[i, j] = np.nan if math.isnan(img[i, j]) else _grad2(img, i, j)


@njit(cache=True, nogil=True, parallel=True)
def _adaptive_step(img, k, w, wi, out):
    """One Saint-Marc iteration: w = exp(-|grad|^2 / (2 k^2)) (0 for NaN pixels), wi = w I, then
    out = sum(w I) / sum(w) over the 3 x 3 neighbourhood inside the image (separable box sums)."""
    rows, cols = img.shape
    scale = -0.5 / (k * k)
    for i in prange(rows):
        for j in range(cols):
            v = img[i, j]
            if math.isnan(v):
                w[i, j] = wi[i, j] = 0.0
            else:
                e = math.exp(_grad2(img, i, j) * scale)
                w[i, j] = e
                wi[i, j] = e * v
    for i in prange(rows):
        cw = np.zeros(cols + 2)
        cwi = np.zeros(cols + 2)
        for r in range(max(i - 1, 0), min(i + 2, rows)):
            for j in range(cols):
                cw[j + 1] += w[r, j]
                cwi[j + 1] += wi[r, j]
        for j in range(cols):
            v = img[i, j]
            sw = cw[j] + cw[j + 1] + cw[j + 2]
            if math.isnan(v):
                out[i, j] = np.nan
            else:
                out[i, j] = (cwi[j] + cwi[j + 1] + cwi[j + 2]) / sw if sw > 0 else v


def saint_marc(img, k=None, iterations=5):
    """Adaptive smoothing (Saint-Marc, Chen & Medioni 1991), iterated:

        I(t+1)(x, y) = sum_{3x3} I(t) w(t) / sum_{3x3} w(t),   w(t) = exp(-|grad I(t)|^2 / (2 k^2))

    (each neighbour weighted by its own gradient, central differences). Pixels on an edge get small
    weights, so edges keep (and sharpen) their contrast while noise is averaged out. k (DN): the
    gradient scale below which the image is smoothed; None takes the median of the non-zero
    gradient magnitudes of the input, every other row and column (adapts to 8-, 12- or 16-bit data).
    NaN pixels get weight 0 and stay NaN. float32 out; the weighted sums are over float32 w and w I
    (relative rounding 6e-8: below 0.005 DN at 65535)."""
    a = _float_image(img)
    if iterations < 0:
        raise InputError(f"the number of smoothing iterations must be >= 0, got {iterations}")
    if k is None:
        g2 = np.empty_like(a)
        _gradient_squared(a, g2)
        sample = g2[::2, ::2]
        sample = sample[sample > 0]  # NaN compares false
        if sample.size == 0:  # constant image: nothing to smooth
            return a
        k = math.sqrt(float(np.median(sample)))
        del g2, sample
    if not k > 0:
        raise InputError(f"the Saint-Marc scale k must be > 0, got {k}")
    w, wi, out = np.empty_like(a), np.empty_like(a), np.empty_like(a)
    for _ in range(iterations):
        _adaptive_step(a, float(k), w, wi, out)
        a, out = out, a
    return a


@njit(cache=True, nogil=True, parallel=True)
def _block_mean(src, f, out):
    """out[i, j] = mean of the valid pixels of src[f i:f (i + 1), f j:f (j + 1)] (NaN if none)."""
    rows, cols = src.shape
    for i in prange(out.shape[0]):
        for j in range(out.shape[1]):
            s = 0.0
            n = 0
            for r in range(f * i, min(f * (i + 1), rows)):
                for c in range(f * j, min(f * (j + 1), cols)):
                    v = src[r, c]
                    if not math.isnan(v):
                        s += v
                        n += 1
            out[i, j] = s / n if n else np.nan


def _check_factor(factor):
    if int(factor) != factor or factor < 2:
        raise InputError(f"the pyramid factor must be an integer >= 2, got {factor}")


def pyramid(img, levels, factor=3):
    """Image pyramid (Zhang and Gruen 2004, section 3.1): [level 0 = the input as float32, level 1, ... level
    levels - 1], each level the mean over factor x factor blocks of the level below (module docstring for the
    pixel convention); sizes ceil(size / factor) per level."""
    _check_factor(factor)
    if int(levels) != levels or levels < 1:
        raise InputError(f"the number of pyramid levels must be an integer >= 1, got {levels}")
    out = [_float_image(img)]
    for _ in range(int(levels) - 1):
        src = out[-1]
        dst = np.empty((-(-src.shape[0] // factor), -(-src.shape[1] // factor)), dtype=np.float32)
        _block_mean(src, int(factor), dst)
        out.append(dst)
    return out


def to_level(x, y, level, factor=3):
    """Full-resolution GDAL image coordinates (x, y) -> coordinates in pyramid level `level`."""
    s = float(factor) ** level
    return np.divide(x, s), np.divide(y, s)


def from_level(x, y, level, factor=3):
    """Coordinates in pyramid level `level` -> full-resolution GDAL image coordinates."""
    s = float(factor) ** level
    return np.multiply(x, s), np.multiply(y, s)


def levels_for(height_range_px, search_px_at_top=4.0, factor=3):
    """Number of pyramid levels (level 0 included) such that a parallax range of height_range_px
    full-resolution pixels (from the height range of the area) shrinks to at most search_px_at_top
    pixels at the top level: the smallest n >= 1 with height_range_px / factor^(n - 1) <= search."""
    _check_factor(factor)
    if not math.isfinite(height_range_px) or height_range_px < 0 or not search_px_at_top > 0:
        raise InputError(
            f"need a finite parallax range >= 0 and a search range > 0 (px), got "
            f"{height_range_px} and {search_px_at_top}"
        )
    n, r = 1, float(height_range_px)
    while r > search_px_at_top:
        r /= factor
        n += 1
    return n
