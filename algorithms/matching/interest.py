"""Foerstner interest operator: from the normal matrix of the gradients summed over a window,
weight w = det / trace and roundness q = 4 det / trace^2; one point per P x P patch (the pixel of
largest w with q > q_min and w > w_factor * median w of the image). Plain numpy (vectorised).
NaN pixels (nodata) are never chosen, nor are pixels whose window or gradients reach one."""

import numpy as np

from ..errors import InputError


def _box(a, win):
    """Sum over win x win windows centred on each pixel ('valid' part padded with 0)."""
    h = win // 2
    c = np.pad(np.cumsum(np.cumsum(a, 0), 1), ((1, 0), (1, 0)))
    out = np.zeros_like(a)
    out[h : a.shape[0] - h, h : a.shape[1] - h] = c[win:, win:] - c[:-win, win:] - c[win:, :-win] + c[:-win, :-win]
    return out


def foerstner(img, window=5):
    """(w, q) images of the Foerstner operator (central-difference gradients, win x win sums);
    0 where the window has no full support or touches a NaN pixel."""
    img = np.asarray(img, dtype=np.float64)
    if img.ndim != 2 or min(img.shape) < window + 2 or window < 3 or window % 2 == 0:
        raise InputError(f"need a 2-D image larger than the odd window ({window}), got {img.shape}")
    valid = np.isfinite(img)
    img = np.where(valid, img, 0.0)
    gx = np.zeros_like(img)
    gy = np.zeros_like(img)
    gx[:, 1:-1] = 0.5 * (img[:, 2:] - img[:, :-2])
    gy[1:-1, :] = 0.5 * (img[2:, :] - img[:-2, :])
    nxx, nyy, nxy = _box(gx * gx, window), _box(gy * gy, window), _box(gx * gy, window)
    det = nxx * nyy - nxy * nxy
    tr = nxx + nyy
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(tr > 0, det / tr, 0.0)
        q = np.where(tr > 0, 4 * det / tr**2, 0.0)
    bad = ~np.isfinite(w) | ~np.isfinite(q)
    if not valid.all():  # the gradients reach one pixel beyond the window
        bad |= _box((~valid).astype(np.float64), window + 2) > 0
    w[bad] = 0.0
    q[bad] = 0.0
    edge = window // 2 + 1  # no full window there
    for a in (w, q):
        a[:edge] = a[-edge:] = 0.0
        a[:, :edge] = a[:, -edge:] = 0.0
    return w, q


def interest_points(img, patch=32, window=5, q_min=0.5, w_factor=1.0, border=0):
    """One point per patch x patch cell, at least `border` pixels from the image edge:
    (x, y, w) arrays in GDAL coordinates, ordered by decreasing w (ties by position)."""
    return best_per_cell(*foerstner(img, window), patch, q_min, w_factor, border)


def best_per_cell(w, q, patch=32, q_min=0.5, w_factor=1.0, border=0):
    """interest_points from the operator's (w, q) images (foerstner; not changed), so that one
    operator serves several patch sizes."""
    if patch < 3:
        raise InputError(f"the patch must be at least 3 pixels, got {patch}")
    w = w.copy()
    if border > 0:
        w[:border] = w[-border:] = 0.0
        w[:, :border] = w[:, -border:] = 0.0
    positive = w[w > 0]
    if positive.size == 0:
        return np.empty(0), np.empty(0), np.empty(0)
    threshold = w_factor * np.median(positive)
    score = np.where((q > q_min) & (w > threshold), w, 0.0)
    nr, nc = (-(-s // patch) for s in score.shape)  # partial cells at the right and bottom count too
    padded = np.zeros((nr * patch, nc * patch))
    padded[: score.shape[0], : score.shape[1]] = score
    cells = padded.reshape(nr, patch, nc, patch).transpose(0, 2, 1, 3).reshape(nr, nc, -1)
    best = cells.argmax(-1)
    value = np.take_along_axis(cells, best[..., None], -1)[..., 0]
    ci, cj = np.nonzero(value > 0)
    b = best[ci, cj]
    i, j = ci * patch + b // patch, cj * patch + b % patch
    order = np.lexsort((j, i, -w[i, j]))
    i, j = i[order], j[order]
    return j + 0.5, i + 0.5, w[i, j]
