"""Three-image matching combinations and point groups (Kornus et al. 2006, section 3.3).

Images in combination order: 0 = the reference (nadir, HRG), 1 = forward (HRS1), 2 = backward
(HRS2). Combinations:

(a) 0-1 (HRG-HRS1): region growing;
(b) 0-2 (HRG-HRS2): the image-0 points of (a) enter as transfer points (only their image-2
    coordinates are matched, the image-0 coordinates of (a) are kept), plus, optionally, points
    region-grown in (b) itself where (a) has none (same STEP cell of image 0);
(c) 2-1 (HRS2-HRS1): the image-2 points of (b) enter as transfer points.

Groups: 1 = two-ray points matched in (a) only or (b) only; 2 = three-ray points matched in two
combinations ((a) and (b), or (b) and (c)); 3 = three-ray points matched in all three, whose
doubly determined image-1 coordinates (from (a) and (c)) are averaged. The deviations from the
average, dx = (x1_a - x1_c) / 2 and dy likewise, are tested against 3 sigma of all such
deviations, separately in x and y as in Kornus et al. 2006. Sigma is robust: 1.4826 * median(|d|), the MAD about
zero (the deviations from a two-value average are +-d by construction, so zero is their centre),
floored at `min_sigma` px so that perfectly consistent data keep all their points. Group 3
points failing the test are dropped (inconsistent: one of the two image-1 matches is wrong, and
which one is unknown); their count is kept in `stats` for the summary (Kornus et al. 2006, Table 1). Points
matched only in (c) do not exist: (c) runs on transfer points only. A two-image block gives
combination (a) and group 1 only. Region growing (region_growing_strategy.py) combines each tile without
the test, applies it with the sigmas of the whole scene, and refines the group 3 points by MPGC in both
search images at once (refinement.py)."""

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..stats import NMAD_SCALE
from .consistency import invert_affine
from .points import COMB_A, COMB_B, COMB_C, OBS_DTYPE, POINT_DTYPE, MultiPoints
from .records import PAIR_DTYPE


def robust_sigma(d, min_sigma=0.0):
    """1.4826 * median(|d|), at least `min_sigma` (0 for an empty d)."""
    d = np.asarray(d, float)
    if d.size == 0:
        return float(min_sigma)
    return max(NMAD_SCALE * float(np.median(np.abs(d))), float(min_sigma))


def _link(src, n_target):
    """For each target index, the index of the record whose `src` names it (first one), else -1."""
    link = np.full(n_target, -1, np.int64)
    src = np.asarray(src, np.int64)
    valid = np.flatnonzero(src >= 0)
    if valid.size:
        if src[valid].max() >= n_target:
            raise InputError("a transfer point refers to a point that does not exist")
        # reversed so that the first record wins
        link[src[valid][::-1]] = valid[::-1]
    return link


class Transfer(NamedTuple):
    """The PAIR_DTYPE records of a combination matched from transfer points, and for each the index of its
    transfer point in the combination before (-1: a point grown in the combination itself)."""

    records: np.ndarray
    src: np.ndarray


def combine(a, b=None, c=None, image_ids=(1, 2, 3), sigma_factor=3.0, min_sigma=0.01, deviations=False):
    """Merge the PAIR_DTYPE results of combinations (a), (b), (c) into a MultiPoints; `b`, `c`: Transfer, or None.

    `b.src[j]` is the index in `a` of the transfer point that b[j] was matched from, or -1 for a
    point grown in (b) itself; `c.src[k]` the index in `b` of the transfer point of c[k] (records
    with -1 are ignored). `image_ids` are the block ids of images 0, 1, 2. Image-0 coordinates
    come from (a) (or from (b) for its own points), image-2 coordinates from (b), so transfer
    points keep their first-image coordinates exactly. With `deviations`, returns (MultiPoints, dx,
    dy): the deviations per point as float64 (POINT_DTYPE keeps them as float32), NaN where not both."""
    b, b_src = (None, None) if b is None else b
    c, c_src = (None, None) if c is None else c
    a = np.asarray(a, PAIR_DTYPE)
    three = b is not None
    b = np.asarray(b if three else np.zeros(0), PAIR_DTYPE)
    b_src = np.asarray(b_src if b_src is not None else np.full(len(b), -1), np.int64)
    c = np.asarray(c if c is not None else np.zeros(0), PAIR_DTYPE)
    c_src = np.asarray(c_src if c_src is not None else np.full(len(c), -1), np.int64)
    if len(b_src) != len(b) or len(c_src) != len(c):
        raise InputError("each transfer result needs its source index")
    if len(c) and not three:
        raise InputError("combination (c) needs combination (b)")
    id0, id1, id2 = (list(image_ids) + [0, 0, 0])[:3]

    a_to_b = _link(b_src, len(a))  # index in b of each a point, -1
    b_to_c = _link(c_src, len(b))  # index in c of each b point, -1
    own_b = np.flatnonzero(b_src < 0)  # points grown in (b) itself
    n_a, n = len(a), len(a) + len(own_b)
    # per point: index into a, b, c (-1 where not matched there)
    ia = np.concatenate([np.arange(n_a), np.full(len(own_b), -1)])
    ib = np.concatenate([a_to_b, own_b])
    ic = np.where(ib >= 0, b_to_c[np.maximum(ib, 0)] if len(b) else -1, -1)

    flags = ((ia >= 0) * COMB_A + (ib >= 0) * COMB_B + (ic >= 0) * COMB_C).astype(np.uint8)
    group = np.array([0, 1, 1, 2, 1, 2, 2, 3], np.int8)[flags]

    def take(records, idx, field, fill=np.nan):
        out = np.full(n, fill, np.float64)
        ok = idx >= 0
        out[ok] = records[field][idx[ok]]
        return out

    rho_a, rho_b, rho_c = take(a, ia, "rho"), take(b, ib, "rho"), take(c, ic, "rho")
    # image 0: (a)'s template positions, else (b)'s
    x0 = np.where(ia >= 0, take(a, ia, "x1"), take(b, ib, "x1"))
    y0 = np.where(ia >= 0, take(a, ia, "y1"), take(b, ib, "y1"))
    # image 1: from (a) and/or (c)
    xa, ya, xc, yc = take(a, ia, "x2"), take(a, ia, "y2"), take(c, ic, "x2"), take(c, ic, "y2")
    ma_a, mi_a = take(a, ia, "semi_major", 0.0), take(a, ia, "semi_minor", 0.0)
    ma_c, mi_c = take(c, ic, "semi_major", 0.0), take(c, ic, "semi_minor", 0.0)
    both = (ia >= 0) & (ic >= 0)
    dx = np.where(both, (xa - xc) / 2.0, np.nan)
    dy = np.where(both, (ya - yc) / 2.0, np.nan)
    sigma_x = robust_sigma(dx[both], min_sigma)
    sigma_y = robust_sigma(dy[both], min_sigma)
    consistent = (np.abs(dx) < sigma_factor * sigma_x) & (np.abs(dy) < sigma_factor * sigma_y)
    keep = ~both | consistent
    x1 = np.where(both, (xa + xc) / 2.0, np.where(ia >= 0, xa, xc))
    y1 = np.where(both, (ya + yc) / 2.0, np.where(ia >= 0, ya, yc))
    # the mean of two independent matches: semi-axes sqrt(s_a^2 + s_c^2) / 2
    maj1 = np.where(both, np.hypot(ma_a, ma_c) / 2.0, np.where(ia >= 0, ma_a, ma_c))
    min1 = np.where(both, np.hypot(mi_a, mi_c) / 2.0, np.where(ia >= 0, mi_a, mi_c))
    rho1 = np.where(both, np.minimum(rho_a, rho_c), np.where(ia >= 0, rho_a, rho_c))
    has1 = (ia >= 0) | (ic >= 0)
    # image 2: (b)'s matched positions (the template of (c) keeps them)
    x2, y2 = take(b, ib, "x2"), take(b, ib, "y2")

    points = np.zeros(n, POINT_DTYPE)
    points["id"] = np.arange(1, n + 1)
    points["group"], points["flags"] = group, flags
    points["rho_a"], points["rho_b"], points["rho_c"] = rho_a, rho_b, rho_c
    points["rho_min"] = np.fmin(np.fmin(rho_a, rho_b), rho_c)
    points["dx"], points["dy"] = dx, dy

    blocks = []
    for image_id, present, col, row, rho, major, minor in [
        (id0, np.ones(n, bool), x0, y0, np.full(n, np.nan), 0.0, 0.0),
        (id1, has1, x1, y1, rho1, maj1, min1),
        (id2, ib >= 0, x2, y2, rho_b, take(b, ib, "semi_major", 0.0), take(b, ib, "semi_minor", 0.0)),
    ]:
        obs = np.zeros(n, OBS_DTYPE)
        obs["point_id"], obs["image_id"] = points["id"], image_id
        obs["col"], obs["row"], obs["rho"] = col, row, rho
        obs["semi_major"], obs["semi_minor"] = major, minor
        blocks.append(obs[present & keep])
    points = points[keep]
    observations = np.concatenate(blocks)
    # renumber 1..n after the 3-sigma test and sort the observations by point, then image
    new_id = np.zeros(n + 1, np.int64)
    new_id[points["id"]] = np.arange(1, len(points) + 1)
    points["id"] = new_id[points["id"]]
    observations["point_id"] = new_id[observations["point_id"]]
    observations = observations[np.lexsort((observations["image_id"], observations["point_id"]))]
    stats = {
        "images": [int(i) for i in (image_ids if three else list(image_ids)[:2])],
        "matched_a": int(len(a)),
        "matched_b": int(len(b)),
        "matched_c": int(len(c)),
        "transfer_b": int(np.count_nonzero(b_src >= 0)),
        "own_b": int(len(own_b)),
        "matched_3": int(np.count_nonzero(both)),
        "rejected_3sigma": int(np.count_nonzero(~keep)),
        "sigma_dx": sigma_x if both.any() else None,
        "sigma_dy": sigma_y if both.any() else None,
        "sigma_factor": float(sigma_factor),
    }
    multi = MultiPoints(points, observations, stats)
    return (multi, dx[keep], dy[keep]) if deviations else multi


def new_cells(x_new, y_new, x_old, y_old, cell):
    """Mask of the (x_new, y_new) that fall in a `cell` x `cell` px cell holding none of the old
    points (used to add (b)'s own points where (a) has none)."""

    def keys(x, y):
        return (np.floor(np.asarray(y) / cell).astype(np.int64) << 32) + np.floor(np.asarray(x) / cell).astype(np.int64)

    return ~np.isin(keys(x_new, y_new), keys(x_old, y_old))


def compose_guide(a, b, b_src):
    """Initial values for combination (c) (image 2 -> image 1) from the points matched in (a) and
    (b): image-2 position from (b), image-1 position from (a), affine A_a A_b^-1 (image 0 -> 1
    after image 2 -> 0). PAIR_DTYPE records; points with a singular affine are left out."""
    a, b = np.asarray(a, PAIR_DTYPE), np.asarray(b, PAIR_DTYPE)
    b_src = np.asarray(b_src, np.int64)
    j = np.flatnonzero(b_src >= 0)
    ra, rb = a[b_src[j]], b[j]
    guide = np.zeros(len(j), PAIR_DTYPE)
    guide["x1"], guide["y1"], guide["x2"], guide["y2"] = rb["x2"], rb["y2"], ra["x2"], ra["y2"]
    guide["rho"] = np.fmin(ra["rho"], rb["rho"])
    a1, a2, a4, a5 = (ra[k].astype(float) for k in ("a1", "a2", "a4", "a5"))
    b1, b2, b4, b5 = invert_affine(rb["a1"], rb["a2"], rb["a4"], rb["a5"])
    c = np.column_stack([a1 * b1 + a2 * b4, a1 * b2 + a2 * b5, a4 * b1 + a5 * b4, a4 * b2 + a5 * b5])
    guide["a1"], guide["a2"], guide["a4"], guide["a5"] = c.T
    guide["r0"], guide["r1"] = 0.0, 1.0
    guide["seed"] = j
    return guide[np.isfinite(c).all(axis=1)]
