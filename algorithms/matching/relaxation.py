"""Resolving the NCC candidates of the coarse-to-fine matcher (Zhang and Gruen 2004).

Hypotheses per point: with two search images, every pair of candidates (one per image) whose
heights agree within `agree` m (the third image's check: both rays meet the reference ray at one
height) is a three-ray hypothesis of height (rho_1 h_1 + rho_2 h_2) / (rho_1 + rho_2) and score
(rho_1 + rho_2) / 2; a point without an agreeing pair (or with one search image) has the
single-image candidates as hypotheses, score rho. A point is unique when it has one hypothesis
and, for a single-image one, its peak ratio second / rho is below `peak_ratio`, or when its best
score beats the second by `margin`.

Relaxation (local smoothness): the other points take, in `rounds` passes, the hypothesis that
best fits the inverse-distance weighted mean height of their resolved neighbours within `radius`
px (neighbours across an edge of `edge_mask` are left out), score - |h - h_nb| / tol, accepted
when |h - h_nb| <= 2 tol; a point without resolved neighbours stays unresolved."""

import numpy as np
from scipy.spatial import cKDTree


def hypotheses(cands, agree):
    """(h, score, i1, i2) arrays (n, H) from the candidate dicts of 1 or 2 search images
    (coarse_to_fine_level.candidates); i1, i2 index the candidates (-1 where that image has none)."""
    c1 = cands[0]
    n, c = c1["h"].shape
    if len(cands) == 1:
        return c1["h"].copy(), c1["rho"].copy(), np.where(np.isfinite(c1["h"]), np.arange(c), -1), np.full((n, c), -1)
    c2 = cands[1]
    i1, i2 = (v.ravel() for v in np.meshgrid(np.arange(c), np.arange(c), indexing="ij"))
    h1, h2 = c1["h"][:, i1], c2["h"][:, i2]
    r1, r2 = c1["rho"][:, i1], c2["rho"][:, i2]
    with np.errstate(invalid="ignore"):
        pair = np.isfinite(h1) & np.isfinite(h2) & (np.abs(h1 - h2) <= agree[:, None])
    hp = np.where(pair, (r1 * h1 + r2 * h2) / (r1 + r2), np.nan)
    sp = np.where(pair, 0.5 * (r1 + r2), np.nan)
    has_pair = pair.any(axis=1)
    # single-image hypotheses only where no pair agrees
    hs = np.concatenate([c1["h"], c2["h"]], axis=1)
    ss = np.concatenate([c1["rho"], c2["rho"]], axis=1)
    hs[has_pair] = np.nan
    ss[has_pair] = np.nan
    h = np.concatenate([hp, hs], axis=1)
    s = np.concatenate([sp, ss], axis=1)
    ones = np.arange(c)
    j1 = np.concatenate([np.broadcast_to(i1, (n, i1.size)), np.broadcast_to(ones, (n, c)), np.full((n, c), -1)], 1)
    j2 = np.concatenate([np.broadcast_to(i2, (n, i2.size)), np.full((n, c), -1), np.broadcast_to(ones, (n, c))], 1)
    ok = np.isfinite(h)
    return h, np.where(ok, s, np.nan), np.where(ok, j1, -1), np.where(ok, j2, -1)


def unique_choice(h, score, i1, i2, cands, peak_ratio, margin):
    """Index of the hypothesis of unique points, -1 elsewhere (module docstring)."""
    n = h.shape[0]
    s = np.where(np.isfinite(score), score, -np.inf)
    order = np.argsort(-s, axis=1, kind="stable")
    best = order[:, 0]
    rows = np.arange(n)
    count = np.isfinite(h).sum(axis=1)
    s1 = s[rows, best]
    s2 = s[rows, order[:, 1]] if h.shape[1] > 1 else np.full(n, -np.inf)
    # the peak ratio of a single-image hypothesis: the image's second local maximum
    second = np.full(n, np.nan)
    for image, idx in ((0, i1[rows, best]), (1, i2[rows, best])):
        if image < len(cands):
            only = (idx >= 0) & ((i2[rows, best] < 0) | (i1[rows, best] < 0))
            second[only] = cands[image]["second"][only]
    pair = (i1[rows, best] >= 0) & (i2[rows, best] >= 0)
    with np.errstate(invalid="ignore"):
        ratio_ok = pair | ~(second / s1 >= peak_ratio)
        ok = (count >= 1) & ratio_ok & ((count == 1) | (s1 - s2 >= margin))
    return np.where(ok, best, -1)


def relax(x, y, scored: tuple[np.ndarray, np.ndarray], choice, tol, radius, rounds=3, edge_mask=None):
    """Choices for the unresolved points (choice -1) by local smoothness (module docstring).
    x, y: point positions (px of the image of `edge_mask`); scored = (h, score): (n, H) hypotheses; tol: (n,)
    height tolerance (m). Returns the updated choice."""
    h, score = scored
    choice = choice.copy()
    n = len(x)
    if n == 0:
        return choice
    tree = cKDTree(np.column_stack([x, y]))
    pairs = tree.query_pairs(radius, output_type="ndarray")
    if edge_mask is not None and len(pairs):
        pairs = pairs[~crosses_edge(edge_mask, x, y, pairs)]
    a = np.concatenate([pairs[:, 0], pairs[:, 1]]) if len(pairs) else np.zeros(0, np.int64)
    b = np.concatenate([pairs[:, 1], pairs[:, 0]]) if len(pairs) else np.zeros(0, np.int64)
    w = 1.0 / (np.hypot(x[a] - x[b], y[a] - y[b]) + 1.0)
    rows = np.arange(n)
    for _ in range(rounds):
        chosen_h = np.where(choice >= 0, h[rows, np.maximum(choice, 0)], np.nan)
        good = np.isfinite(chosen_h[b])
        num = np.bincount(a[good], w[good] * chosen_h[b][good], minlength=n)
        den = np.bincount(a[good], w[good], minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            h_nb = num / den
        todo = (choice < 0) & np.isfinite(h_nb) & np.isfinite(h).any(axis=1)
        if not todo.any():
            break
        dev = np.abs(h[todo] - h_nb[todo, None]) / tol[todo, None]
        fit = np.where(np.isfinite(dev), score[todo] - dev, -np.inf)
        pick = fit.argmax(axis=1)
        ok = dev[np.arange(todo.sum()), pick] <= 2.0
        idx = np.flatnonzero(todo)
        choice[idx[ok]] = pick[ok]
        if not ok.any():
            break
    return choice


def crosses_edge(edge_mask, x, y, pairs, step=0.5, chunk=20_000):
    """For each pair (i, j) of points: does the segment between them pass an edge pixel? (Samples
    every `step` px; `chunk` pairs at a time, so memory stays bounded: a level of 10^6 pairs of
    120 samples would otherwise take gigabytes.)"""
    rows, cols = edge_mask.shape
    d = np.hypot(x[pairs[:, 1]] - x[pairs[:, 0]], y[pairs[:, 1]] - y[pairs[:, 0]])
    k = max(2, int(np.ceil(d.max() / step)) + 1) if len(d) else 2
    t = np.linspace(0.0, 1.0, k)[1:-1]
    out = np.zeros(len(pairs), bool)
    for a in range(0, len(pairs), chunk):
        p = pairs[a : a + chunk]
        sx = x[p[:, 0], None] + t * (x[p[:, 1]] - x[p[:, 0]])[:, None]
        sy = y[p[:, 0], None] + t * (y[p[:, 1]] - y[p[:, 0]])[:, None]
        i = np.clip(np.floor(sy).astype(np.int64), 0, rows - 1)
        j = np.clip(np.floor(sx).astype(np.int64), 0, cols - 1)
        out[a : a + chunk] = edge_mask[i, j].any(axis=1)
    return out
