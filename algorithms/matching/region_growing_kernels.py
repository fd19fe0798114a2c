"""Numba kernels of region growing (region_growing.py): the priority list of matched lattice
nodes and the growth of one tile.

The list is a binary heap keyed by the correlation coefficient rho, rounded to 1e-6 (`_quantise`)
so that rounding noise between builds cannot reorder it; ties go to the smaller node index, so a
growth is deterministic. A node is matched by LSM (lsm.lsm_point) and accepted when

    status ok, rho > rho_min, semi-major axis < max_ellipse, shift < max_shift, iterations < max_iter

(`_passes`); a failure inside the image is tried again with the wide window when one is given.
Growth pops the best node and matches its four neighbours at distance STEP (_DC, _DR: left, right,
up, down) from its position transported by the affine (a1, a2, a4, a5): its own, or the models'
prior for the tile. All kernels are nogil, so tiles run on threads."""

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from .lsm import OUTSIDE, Start, lsm_point, template_units


class Tile(NamedTuple):
    """A tile's windows and lattice: img1, img2 are windows whose top-left corners lie at image positions (ox1,
    oy1), (ox2, oy2); the nx x ny lattice nodes (node = row * nx + col) lie at image-1 positions (gx0 + col step,
    gy0 + row step)."""

    img1: np.ndarray
    img2: np.ndarray
    ox1: float
    oy1: float
    ox2: float
    oy2: float
    gx0: float
    gy0: float
    step: float
    nx: int
    ny: int


class Accept(NamedTuple):
    """The acceptance criteria: rho > rho_min, semi-major axis < max_ellipse (px), shift < max_shift (px),
    iterations < max_iter."""

    rho_min: float
    max_ellipse: float
    max_shift: float
    max_iter: int


_DC = np.array([-1, 1, 0, 0], np.int64)
_DR = np.array([0, 0, -1, 1], np.int64)


@njit(cache=True, nogil=True)
def _quantise(rho):
    """Heap key: rho rounded to 1e-6, so rounding noise between builds cannot reorder the list
    (ties go to the smaller node index)."""
    return math.floor(rho * 1e6 + 0.5) * 1e-6


@njit(cache=True, nogil=True)
def _before(k1, n1, k2, n2):
    """Heap order: larger rho first, ties by smaller node index (deterministic)."""
    return k1 > k2 or (k1 == k2 and n1 < n2)


@njit(cache=True, nogil=True)
def _push(key, node, size, k, n):
    i = size
    key[i] = k
    node[i] = n
    while i > 0:
        p = (i - 1) // 2
        if _before(key[i], node[i], key[p], node[p]):
            key[i], key[p] = key[p], key[i]
            node[i], node[p] = node[p], node[i]
            i = p
        else:
            break
    return size + 1


@njit(cache=True, nogil=True)
def _pop(key, node, size):
    """Remove the top of the heap; returns the new size (the caller read node[0] before)."""
    size -= 1
    key[0] = key[size]
    node[0] = node[size]
    i = 0
    while True:
        left = 2 * i + 1
        right = left + 1
        best = i
        if left < size and _before(key[left], node[left], key[best], node[best]):
            best = left
        if right < size and _before(key[right], node[right], key[best], node[best]):
            best = right
        if best == i:
            break
        key[i], key[best] = key[best], key[i]
        node[i], node[best] = node[best], node[i]
        i = best
    return size


@njit(cache=True, nogil=True)
def _passes(status, out, accept):
    """The acceptance criteria."""
    return (
        status == 0
        and out[2] > accept.rho_min
        and out[3] < accept.max_ellipse
        and out[5] < accept.max_shift
        and out[6] < accept.max_iter
    )


@njit(cache=True, nogil=True)
def _attempt(tile, node, start, solve, wide, accept, out, results, state):
    """LSM at lattice node `node` of the Tile `tile` from the Start `start` (image coordinates) with the Solver
    `solve`, again with the Solver `wide` (a larger half-size) where the match failed inside the image (its error
    ellipse then reported in the template's units, as lsm.match_accepted's); stores the result (image coordinates)
    and the state (1 accepted, 2 rejected); returns whether accepted."""
    x1 = tile.gx0 + (node % tile.nx) * tile.step - tile.ox1
    y1 = tile.gy0 + (node // tile.nx) * tile.step - tile.oy1
    local = Start(start.x2 - tile.ox2, start.y2 - tile.oy2, start.a1, start.a2, start.a4, start.a5)
    status = lsm_point(tile.img1, tile.img2, x1, y1, local, solve, out)
    ok = _passes(status, out, accept)
    if not ok and status != OUTSIDE and wide.half > solve.half:
        status = lsm_point(tile.img1, tile.img2, x1, y1, local, wide, out)
        ok = _passes(status, out, accept)
        out[3:5] *= template_units(wide.half, solve.half)  # the ellipse in the template's units
    for f in range(out.shape[0]):
        results[node, f] = out[f]
    results[node, 0] += tile.ox2
    results[node, 1] += tile.oy2
    state[node] = 1 if ok else 2
    return ok


@njit(cache=True, nogil=True)
def grow_kernel(tile, seeds, solve, wide, accept, results, state, origin, prior):
    """Region growing on the lattice of the Tile `tile`. seeds: (ns, 8) rows (node, x2, y2, a1, a2, a4, a5, seed
    id) of initial values in image coordinates, tried in order; LSM with the Solver `solve` (and `wide` where it
    fails inside the images, when wide.half > solve.half), the Accept criteria `accept`. Fills results (nodes,
    LSM_OUT; image coordinates), state (0 untried, 1 accepted, 2 rejected) and origin (seed id per node).
    prior: the models' (a1, a2, a4, a5) for the tile, the initial affine of every neighbour (the popped point's
    own affine when prior is empty: as in Hofmann et al.); returns the number of LSM attempts."""
    nx = tile.nx
    n = nx * tile.ny
    key = np.empty(n)
    hnode = np.empty(n, np.int64)
    size = 0
    out = np.empty(results.shape[1])
    tries = 0
    for s in range(seeds.shape[0]):
        node = int(seeds[s, 0])
        if node < 0 or node >= n or state[node] != 0:
            continue
        tries += 1
        start = Start(seeds[s, 1], seeds[s, 2], seeds[s, 3], seeds[s, 4], seeds[s, 5], seeds[s, 6])
        if _attempt(tile, node, start, solve, wide, accept, out, results, state):
            origin[node] = int(seeds[s, 7])
            size = _push(key, hnode, size, _quantise(results[node, 2]), node)
    while size > 0:
        node = hnode[0]
        size = _pop(key, hnode, size)
        r = node // nx
        c = node % nx
        for d in range(4):
            cc = c + _DC[d]
            rr = r + _DR[d]
            if cc < 0 or cc >= nx or rr < 0 or rr >= tile.ny:
                continue
            nb = rr * nx + cc
            if state[nb] != 0:
                continue
            dk = _DC[d] * tile.step
            dl = _DR[d] * tile.step
            a1 = results[node, 7]
            a2 = results[node, 8]
            a4 = results[node, 9]
            a5 = results[node, 10]
            if prior.shape[0] == 4:  # the models' affine: no drift along long growth paths
                a1 = prior[0]
                a2 = prior[1]
                a4 = prior[2]
                a5 = prior[3]
            tries += 1
            start = Start(results[node, 0] + a1 * dk + a2 * dl, results[node, 1] + a4 * dk + a5 * dl, a1, a2, a4, a5)
            if _attempt(tile, nb, start, solve, wide, accept, out, results, state):
                origin[nb] = origin[node]
                size = _push(key, hnode, size, _quantise(results[nb, 2]), nb)
    return tries
