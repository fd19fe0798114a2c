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
combination (a) and group 1 only. match_block then refines the group 3 points by MPGC in both
search images at once (refinement.py; `refine`, on by default). match_block runs tile by tile
(block_tiles.py), with the test's sigmas and MPGC's orientation of the whole scene."""
import os

import numpy as np

from ..errors import InputError
from ..stats import NMAD_SCALE
from .consistency import invert_affine
from .points import COMB_A, COMB_B, COMB_C, OBS_DTYPE, POINT_DTYPE, MultiPoints
from .records import PAIR_DTYPE


def combination_order(rows, text):
    """The block's image rows in combination order: `text` is a comma-separated list of names
    (reference, forward[, backward]); empty or 'all' orders the block's 2 or 3 images itself
    (HRG, HRS1, HRS2 when so named, else block order). InputError for a block of fewer than 2 images,
    whatever `text` names."""
    if len(rows) < 2:
        has = f"one image ({rows[0]['name']})" if rows else "no image"
        raise InputError(f"matching needs two or three images of the same ground, and the block has {has}: create a "
                         "block with the stereo pair or triplet (pushbroom:createblock with all its images) and match "
                         "that")
    by_name = {r["name"]: r for r in rows}
    names = [n.strip() for n in (text or "").split(",") if n.strip()]
    if names and names != ["all"]:
        missing = [n for n in names if n not in by_name]
        if missing:
            raise InputError(f"image(s) {', '.join(missing)} not in the block; it has {', '.join(by_name)}")
        if len(names) not in (2, 3) or len(set(names)) != len(names):
            raise InputError(f"give 2 or 3 different images (reference, forward[, backward]), got {names}")
        return [by_name[n] for n in names]
    if len(rows) not in (2, 3):
        raise InputError(f"the block has {len(rows)} images: name the 2 or 3 to match in the Images parameter "
                         "(reference, forward[, backward])")
    upper = {r["name"].upper(): r for r in rows}
    if len(rows) == 3 and all(any(k.startswith(p) for k in upper) for p in ("HRG", "HRS1", "HRS2")):
        return [next(r for k, r in upper.items() if k.startswith(p)) for p in ("HRG", "HRS1", "HRS2")]
    return list(rows)


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


def combine(a, b=None, b_src=None, c=None, c_src=None, image_ids=(1, 2, 3), sigma_factor=3.0,
            min_sigma=0.01, deviations=False):
    """Merge the PAIR_DTYPE results of combinations (a), (b), (c) into a MultiPoints.

    `b_src[j]` is the index in `a` of the transfer point that b[j] was matched from, or -1 for a
    point grown in (b) itself; `c_src[k]` the index in `b` of the transfer point of c[k] (records
    with -1 are ignored). `image_ids` are the block ids of images 0, 1, 2. Image-0 coordinates
    come from (a) (or from (b) for its own points), image-2 coordinates from (b), so transfer
    points keep their first-image coordinates exactly. With `deviations`, returns (MultiPoints, dx,
    dy): the deviations per point as float64 (POINT_DTYPE keeps them as float32), NaN where not both."""
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

    a_to_b = _link(b_src, len(a))           # index in b of each a point, -1
    b_to_c = _link(c_src, len(b))           # index in c of each b point, -1
    own_b = np.flatnonzero(b_src < 0)       # points grown in (b) itself
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
            (id2, ib >= 0, x2, y2, rho_b, take(b, ib, "semi_major", 0.0), take(b, ib, "semi_minor", 0.0))]:
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
    stats = {"images": [int(i) for i in (image_ids if three else list(image_ids)[:2])],
             "matched_a": int(len(a)), "matched_b": int(len(b)), "matched_c": int(len(c)),
             "transfer_b": int(np.count_nonzero(b_src >= 0)), "own_b": int(len(own_b)),
             "matched_3": int(np.count_nonzero(both)), "rejected_3sigma": int(np.count_nonzero(~keep)),
             "sigma_dx": sigma_x if both.any() else None, "sigma_dy": sigma_y if both.any() else None,
             "sigma_factor": float(sigma_factor)}
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


def pair_seeds(image1, image2, model1, model2, seed_points, id1, id2, params=None, height_range=None):
    """PAIR_DTYPE seeds from the points of `seed_points` (MultiPoints) observed in both images
    `id1` and `id2`: each is re-matched from its stored image-2 position on the images the growth
    uses (region_growing.transfer_points) and kept if it passes the acceptance criteria."""
    from .region_growing import transfer_points
    x1, y1 = seed_points.coordinates(id1)
    x2, y2 = seed_points.coordinates(id2)
    both = np.isfinite(x1) & np.isfinite(y1) & np.isfinite(x2) & np.isfinite(y2)
    if not both.any():
        return np.zeros(0, PAIR_DTYPE)
    recs, ok = transfer_points(image1, image2, model1, model2, x1[both], y1[both], params, height_range,
                               x2=x2[both], y2=y2[both])
    return recs[ok]


def match_block(images, models, names=None, image_ids=None, params=None, height_range=None, seed_points=None,
                automatic=True, feedback=None, workers=1, grow_second=True, sigma_factor=3.0, refine=True):
    """Match 2 or 3 images in combination order (reference/nadir, forward, backward) and return
    the MultiPoints of `combine`. `images` are whatever region_growing.match_pair takes (arrays),
    `image_ids` the block ids (default 1, 2, 3), `names` only label the log. Seeds: the points
    of `seed_points` (MultiPoints with block image ids: tie or control points) seen in the
    reference and the other image of a region-grown pair, re-matched there (pair_seeds), and/or
    `automatic` ones in every tile. With `grow_second`, combination (b) is also region-grown for
    points where (a) found none; with `refine`, MPGC refines the group 3 points
    (refinement.refine_three_ray). The tiles run on `workers` (threads, or an execution.Execution
    whose workers see this machine's temporary folder) by block_tiles.match_tiles, and the points
    are gathered here: for a whole scene, the matching step writes them part by part instead."""
    import tempfile

    from ..execution import Execution
    from .block_tiles import match_tiles
    execution = workers if isinstance(workers, Execution) else Execution("threads", max(int(workers), 1))
    parts, stats = match_tiles(images, models, os.path.join(tempfile.gettempdir(), "pushbroom-matching"),
                               names=names, image_ids=image_ids, params=params, height_range=height_range,
                               seed_points=seed_points, automatic=automatic, feedback=feedback, execution=execution,
                               grow_second=grow_second, sigma_factor=sigma_factor, refine=refine)
    if not parts:
        return MultiPoints(stats=stats)
    return MultiPoints(np.concatenate([p.points for p in parts]), np.concatenate([p.observations for p in parts]),
                       stats)


def summary_rows(points, rho_dem=0.7, stats=None):
    """Counts per group like Kornus et al. 2006, Table 1: a list of (label, value). `points` is a
    MultiPoints, or a list of parts (MultiPoints, or functions returning one, taken one at a time) with
    the run's `stats`."""
    parts = [points] if isinstance(points, MultiPoints) else points
    stats = points.stats if isinstance(points, MultiPoints) else dict(stats or {})
    counts = np.zeros(7, np.int64)
    for part in parts:
        p = (part if isinstance(part, MultiPoints) else part()).points
        g1, g2, g3 = (p["group"] == 1), (p["group"] == 2), (p["group"] == 3)
        high = p["rho_min"] > rho_dem
        counts += [g1.sum(), (g1 & high).sum(), g2.sum(), (g2 & high).sum(), g3.sum(), ((g2 | g3) & high).sum(),
                   len(p)]
    n1, n1_high, n2, n2_high, n3, n23_high, total = (int(c) for c in counts)
    rows = [("Two-ray points (group 1)", n1),
            (f"Two-ray points with rho > {rho_dem:g}", n1_high),
            ("Three-ray points matched in 2 combinations (group 2)", n2),
            (f"Three-ray points in 2 combinations with rho > {rho_dem:g}", n2_high),
            ("Points matched in 3 combinations", int(stats.get("matched_3", n3))),
            (f"Points in 3 combinations with |d| < {stats.get('sigma_factor', 3.0):g} sigma (group 3)", n3),
            (f"Three-ray points selected for DEM generation (rho > {rho_dem:g})", n23_high),
            ("All points", total)]
    for key, label in [("sigma_dx", "sigma of dx (px, robust)"), ("sigma_dy", "sigma of dy (px, robust)")]:
        if stats.get(key) is not None:
            rows.append((label, round(float(stats[key]), 4)))
    if "refined_mpgc" in stats:
        rows.append(("Group 3 points refined by MPGC", int(stats["refined_mpgc"])))
    return rows


def format_summary(rows):
    """The summary rows as aligned text for the log."""
    width = max(len(label) for label, _ in rows)
    return "\n".join(f"{label:<{width}}  {value:>12}" if isinstance(value, int) else f"{label:<{width}}  {value:>12g}"
                     for label, value in rows)


def write_summary_csv(path, rows):
    """Write the summary rows as CSV (item,value) atomically."""
    from ..atomic import write_text
    lines = ["item,value"] + [f"\"{label}\",{value}" for label, value in rows]
    write_text(path, "\n".join(lines) + "\n")
    return path
