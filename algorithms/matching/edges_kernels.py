"""numba kernels of edges.py: Canny non-maximum suppression and hysteresis, edge-pixel thinning and
chain tracing, edgel candidates along quasi-epipolar paths, and the figural-continuity dynamic
programme. Array indices are (row, col); positions handed to bilinear/ncc_path are GDAL's."""

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..interpolation import bilinear
from .ncc import ncc_path

#: the 8 neighbours (d_row, d_col) counter-clockwise from east: E, NE, N, NW, W, SW, S, SE
DR = np.array([0, -1, -1, -1, 0, 1, 1, 1])
DC = np.array([1, 1, 0, -1, -1, -1, 0, 1])


# --------------------------------------------------------------------------------------------
# Canny


@njit(cache=True, nogil=True)
def nms(gx, gy, mag, allowed, out):
    """Non-maximum suppression with the magnitude interpolated linearly between the two pixels
    that bracket the gradient direction on either side (step 1 along the dominant axis). A pixel
    is kept if its magnitude is > the one behind it and >= the one ahead (one pixel of a symmetric
    ridge survives). Only `allowed` pixels with magnitude > 0 can be kept; the 1-pixel border never."""
    nr, nc = mag.shape
    out[:] = False
    for i in range(1, nr - 1):
        for j in range(1, nc - 1):
            m = mag[i, j]
            if not allowed[i, j] or not m > 0.0:
                continue
            ax, ay = abs(gx[i, j]), abs(gy[i, j])
            sx = 1 if gx[i, j] >= 0.0 else -1
            sy = 1 if gy[i, j] >= 0.0 else -1
            if ax >= ay:
                w = ay / ax
                ahead = (1.0 - w) * mag[i, j + sx] + w * mag[i + sy, j + sx]
                behind = (1.0 - w) * mag[i, j - sx] + w * mag[i - sy, j - sx]
            else:
                w = ax / ay
                ahead = (1.0 - w) * mag[i + sy, j] + w * mag[i + sy, j + sx]
                behind = (1.0 - w) * mag[i - sy, j] + w * mag[i - sy, j - sx]
            out[i, j] = m > behind and m >= ahead


@njit(cache=True, nogil=True)
def hysteresis(weak, strong, out):
    """out = the 8-connected components of `weak` that contain a `strong` pixel (flood fill)."""
    nr, nc = weak.shape
    out[:] = False
    stack = np.empty(weak.size, np.int64)
    for i0 in range(nr):
        for j0 in range(nc):
            if not strong[i0, j0] or not weak[i0, j0] or out[i0, j0]:
                continue
            out[i0, j0] = True
            top = 0
            stack[0] = i0 * nc + j0
            while top >= 0:
                p = stack[top]
                top -= 1
                i, j = p // nc, p % nc
                for k in range(8):
                    a, b = i + DR[k], j + DC[k]
                    if 0 <= a < nr and 0 <= b < nc and weak[a, b] and not out[a, b]:
                        out[a, b] = True
                        top += 1
                        stack[top] = a * nc + b


# --------------------------------------------------------------------------------------------
# linking


@njit(cache=True, nogil=True)
def _on(mask, i, j):
    return 0 <= i < mask.shape[0] and 0 <= j < mask.shape[1] and mask[i, j]


@njit(cache=True, nogil=True)
def _count(mask, i, j):
    n = 0
    for k in range(8):
        if _on(mask, i + DR[k], j + DC[k]):
            n += 1
    return n


@njit(cache=True, nogil=True)
def thin_corners(mask):
    """Removes, in raster order until nothing changes, the pixels with >= 2 neighbours whose
    removal keeps the 8-connectivity of their neighbourhood (Yokoi connectivity number N8 = 1):
    the redundant corner pixels of staircases and small triangles, which would otherwise look like
    junctions. Line ends (1 neighbour) and line pixels (N8 = 2) stay."""
    changed = True
    while changed:
        changed = False
        for i in range(mask.shape[0]):
            for j in range(mask.shape[1]):
                if not mask[i, j] or _count(mask, i, j) < 2:
                    continue
                n8 = 0
                for k in range(0, 8, 2):
                    c0 = not _on(mask, i + DR[k], j + DC[k])
                    c1 = not _on(mask, i + DR[(k + 1) % 8], j + DC[(k + 1) % 8])
                    c2 = not _on(mask, i + DR[(k + 2) % 8], j + DC[(k + 2) % 8])
                    n8 += int(c0) - int(c0 and c1 and c2)
                if n8 == 1:
                    mask[i, j] = False
                    changed = True


@njit(cache=True, nogil=True)
def _attach_junction(junction, i, j, rows, cols, n, skip_i, skip_j):
    """Appends a junction pixel next to (i, j) (4-neighbours first, never (skip_i, skip_j)) to
    rows/cols; returns n."""
    for k in (0, 2, 4, 6, 1, 3, 5, 7):
        a, b = i + DR[k], j + DC[k]
        if _on(junction, a, b) and not (a == skip_i and b == skip_j):
            rows[n] = a
            cols[n] = b
            return n + 1
    return n


@njit(cache=True, nogil=True)
def _walk(mask, junction, seen, i, j, rows, cols, n):
    """Follows the unvisited non-junction pixels from (i, j) (appended first); returns n."""
    while True:
        seen[i, j] = True
        rows[n] = i
        cols[n] = j
        n += 1
        found = False
        for k in (0, 2, 4, 6, 1, 3, 5, 7):
            a, b = i + DR[k], j + DC[k]
            if _on(mask, a, b) and not junction[a, b] and not seen[a, b]:
                i, j = a, b
                found = True
                break
        if not found:
            return n


@njit(cache=True, nogil=True)
def trace(mask):
    """Chains of a thinned edge mask. Junctions are the pixels with >= 3 neighbours; chains run
    over the other pixels from one end to the other, each end extended by an adjacent junction
    pixel (so chains meet at junctions); closed contours start at their first pixel in raster
    order. Returns (rows, cols, starts): chain c is rows/cols[starts[c]:starts[c + 1]]."""
    nr, nc = mask.shape
    junction = np.zeros(mask.shape, np.bool_)
    for i in range(nr):
        for j in range(nc):
            junction[i, j] = mask[i, j] and _count(mask, i, j) >= 3
    seen = np.zeros(mask.shape, np.bool_)
    rows = np.empty(3 * mask.sum() + 2, np.int64)
    cols = np.empty_like(rows)
    starts = [0]
    n = 0
    for loops in (False, True):
        for i in range(nr):
            for j in range(nc):
                if not mask[i, j] or junction[i, j] or seen[i, j]:
                    continue
                free = 0
                for k in range(8):
                    a, b = i + DR[k], j + DC[k]
                    if _on(mask, a, b) and not junction[a, b]:
                        free += 1
                if not loops and free > 1:
                    continue
                begin = n
                n = _attach_junction(junction, i, j, rows, cols, n, -1, -1)
                n = _walk(mask, junction, seen, i, j, rows, cols, n)
                if not loops:
                    n = _attach_junction(junction, rows[n - 1], cols[n - 1], rows, cols, n, rows[begin], cols[begin])
                starts.append(n)
    return rows[:n], cols[:n], np.array(starts, np.int64)


# --------------------------------------------------------------------------------------------
# edgel matching


class Gradients(NamedTuple):
    """The reference's (g1x, g1y) and the search image's (g2x, g2y) gradient images."""

    g1x: np.ndarray
    g1y: np.ndarray
    g2x: np.ndarray
    g2y: np.ndarray


class EdgelCriteria(NamedTuple):
    """An edgel candidate's criteria: NCC template half-size (px), the lowest rho, the cosine of the largest angle
    between the mapped and the search gradient, the weight of the direction in the cost, and the sine of the
    smallest angle between the mapped gradient's edge and the path."""

    half: int
    rho_floor: float
    cos_min: float
    dir_weight: float
    cross_min: float


class Ranked(NamedTuple):
    """The candidates of each edgel (n, K), least cost first: path parameter t (samples), rho, cost; and their
    count (n,)."""

    t: np.ndarray
    rho: np.ndarray
    cost: np.ndarray
    count: np.ndarray


@njit(cache=True, nogil=True, parallel=True)
def edgel_candidates(ref, search, grads, x1, y1, px, py, aff, criteria, ranked):
    """Candidates of edgel i = the local NCC maxima along its path (px[i], py[i]) (end samples
    excluded) with rho >= rho_floor whose search-image gradient direction is within acos(cos_min)
    of the reference gradient mapped by the inverse transposed affine A^-T g1 (a dark-to-bright
    edge stays dark-to-bright). None where the mapped gradient is closer than acos(cross_min) to
    perpendicular to the path (the edge too close to parallel to the quasi-epipolar line to fix a
    disparity). Sub-pixel path parameter t (samples) and rho by a parabola; kept are the
    K = cand_t.shape[1] of least cost (1 - rho) + dir_weight (1 - cos), ordered by cost: `ranked` (Ranked)."""
    g1x, g1y, g2x, g2y = grads
    half, rho_floor, cos_min, dir_weight, cross_min = criteria
    cand_t, cand_rho, cand_cost, ncand = ranked
    n, m = px.shape
    kmax = cand_t.shape[1]
    for i in prange(n):
        ncand[i] = 0
        rho = np.empty(m)
        a1, a2, a4, a5 = aff[i, 0], aff[i, 1], aff[i, 2], aff[i, 3]
        ncc_path(ref, search, x1[i], y1[i], half, px[i], py[i], a1, a2, a4, a5, rho)
        gx, gy = bilinear(g1x, x1[i], y1[i]), bilinear(g1y, x1[i], y1[i])
        det = a1 * a5 - a2 * a4
        if not (math.isfinite(gx) and math.isfinite(gy) and math.isfinite(det)) or det == 0.0:
            continue
        ex = (a5 * gx - a4 * gy) / det  # A^-T g1
        ey = (-a2 * gx + a1 * gy) / det
        en = math.hypot(ex, ey)
        ux, uy = px[i, m - 1] - px[i, 0], py[i, m - 1] - py[i, 0]
        un = math.hypot(ux, uy)
        if not (en > 0.0 and un > 0.0) or abs(ex * ux + ey * uy) < cross_min * en * un:
            continue
        for j in range(1, m - 1):
            r0, r1, r2 = rho[j - 1], rho[j], rho[j + 1]
            if not (r1 >= r0 and r1 > r2 and r1 >= rho_floor):
                continue
            den = r0 - 2.0 * r1 + r2
            d = 0.5 * (r0 - r2) / den if den < 0.0 else 0.0
            d = min(max(d, -0.5), 0.5)
            r = min(r1 - 0.25 * (r0 - r2) * d, 1.0)
            t = j + d
            j0 = min(int(math.floor(t)), m - 2)
            f = t - j0
            cx = px[i, j0] * (1.0 - f) + px[i, j0 + 1] * f
            cy = py[i, j0] * (1.0 - f) + py[i, j0 + 1] * f
            hx, hy = bilinear(g2x, cx, cy), bilinear(g2y, cx, cy)
            hn = math.hypot(hx, hy)
            if not hn > 0.0:
                continue
            c = (ex * hx + ey * hy) / (en * hn)
            if c < cos_min:
                continue
            cost = (1.0 - r) + dir_weight * (1.0 - c)
            k = ncand[i]
            if k == kmax:
                if cost >= cand_cost[i, kmax - 1]:
                    continue
                k = kmax - 1
            else:
                ncand[i] += 1
            while k > 0 and cand_cost[i, k - 1] > cost:  # insertion by cost
                cand_t[i, k], cand_rho[i, k] = cand_t[i, k - 1], cand_rho[i, k - 1]
                cand_cost[i, k] = cand_cost[i, k - 1]
                k -= 1
            cand_t[i, k], cand_rho[i, k], cand_cost[i, k] = t, r, cost


@njit(cache=True, nogil=True)
def figural_dp(starts, index, step, ncand, cand_d, cand_cost, jump_cost, jump_tol, skip_cost, max_skip, choice):
    """Figural continuity per chain (edgels of chain c: starts[c]:starts[c + 1], in order along the
    chain, index = their position in the chain): the candidate sequence of least total cost
        sum unary cost + sum jump_cost max(0, |d_a - d_b| - jump_tol (index_b - index_a) / step)
        + skip_cost per edgel with candidates left out (at most max_skip in a row inside the path),
    where d is the candidate's position along the quasi-epipolar path in px (so a jump is a
    disparity change in px whatever the images' scales). choice[e] = candidate or -1 (skipped)."""
    kmax = cand_d.shape[1]
    choice[:] = -1
    for c in range(starts.size - 1):
        e0, e1 = starts[c], starts[c + 1]
        live = np.empty(e1 - e0, np.int64)
        nl = 0
        for e in range(e0, e1):
            if ncand[e] > 0:
                live[nl] = e
                nl += 1
        if nl == 0:
            continue
        acc = np.full((nl, kmax), np.inf)
        back_e = np.full((nl, kmax), -1, np.int64)
        back_k = np.full((nl, kmax), -1, np.int64)
        for a in range(nl):
            ea = live[a]
            for k in range(ncand[ea]):
                best = skip_cost * a  # start here, skipping all before
                be, bk = -1, -1
                for b in range(max(0, a - 1 - max_skip), a):
                    eb = live[b]
                    gap = (index[ea] - index[eb]) / step
                    for q in range(ncand[eb]):
                        jump = abs(cand_d[ea, k] - cand_d[eb, q]) - jump_tol * gap
                        v = acc[b, q] + skip_cost * (a - b - 1) + jump_cost * max(jump, 0.0)
                        if v < best:
                            best, be, bk = v, b, q
                acc[a, k] = best + cand_cost[ea, k]
                back_e[a, k], back_k[a, k] = be, bk
        best = np.inf
        ba, bk = -1, -1
        for a in range(nl):
            for k in range(ncand[live[a]]):
                v = acc[a, k] + skip_cost * (nl - 1 - a)  # end here, skipping all after
                if v < best:
                    best, ba, bk = v, a, k
        while ba >= 0:
            choice[live[ba]] = bk
            ba, bk = back_e[ba, bk], back_k[ba, bk]
