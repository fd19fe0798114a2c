"""Dense matching of a pair or a triplet, tile by tile on the chosen execution, into the same point parts as
region growing (matching/points.py's MultiPoints, block/points.save_part), so that the rest of the chain reads
them unchanged.

The tiles are the reference image's (tiling.tile_grid of DenseParams.tile px). Each is a task in two rounds:
1. `_dense_tile`: for each pair (reference, forward) and, for a triplet, (reference, backward), the lattice
   nodes' image-2 positions (pair_tile.match_pair_tile); a node becomes a point where one pair matched it (group
   1, two rays) or both did (group 2, three rays from the two combinations; flags COMB_A, COMB_B as region
   growing's). Written to a work file; the task returns its counts.
2. `_finish_tile`: the points numbered on from the tiles before it (ids 1 ... N in tile order) and handed to
   `write_part`.

Observations: the reference image's position is the lattice node (rho NaN, axes 0: the template, as region
growing's); a matched image's position carries LSM's rho and error-ellipse semi-axes where the refinement
(refine.py) replaced it, NaN where it stayed the semi-global matcher's. A point's rho_a / rho_b are its pairs'
LSM rho; rho_min the smaller, NaN where one of its matched positions is unrefined (a point is "refined" only
if all of them are: the DEM's tiers and the tie point selection read it); flags DENSE. A tile without texture
gives no points and a warning, not an error.

The images are opened once, masking their nodata (the band's value and GDAL mask) and saturated pixels
(matching.imagery.Image, saturation=True): a node whose census window or LSM template reaches a masked pixel,
or whose candidate conjugates do, yields no point (pair_tile.py, refine.py).

The result does not depend on the execution or the number of workers: a tile's points depend only on its box."""
import os
from typing import NamedTuple

import numpy as np

from .. import progress
from ..atomic import save_array, work_dir
from ..execution import run_tasks, session
from ..matching.block_tiles import BIAS_SAMPLE, block_inputs, first_ids
from ..matching.imagery import as_image
from ..matching.orientation_bias import affine_bias
from ..matching.params import GrowParams
from ..matching.points import COMB_A, COMB_B, DENSE, OBS_DTYPE, POINT_DTYPE, REFINED, MultiPoints
from ..matching.refinement import MIN_POINTS, refine_three_ray
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .pair_tile import match_pair_tile
from .params import DenseParams
from .refine import isolated, refine_positions


class DenseJob(NamedTuple):
    """What every tile shares."""

    images: list
    models: list
    image_ids: list
    params: DenseParams
    height_range: object
    write_part: object      # write_part(folder, k, MultiPoints) -> index entry (module-level), or None
    bias: object = None     # DenseParams.mpgc: (corrected models, systematic px) of the scene's sample


def tile_points(job, box):
    """The MultiPoints of one tile (ids 1 ... n in lattice order) and its per-pair information."""
    n = len(job.images)
    positions, quality, infos = [], [], []
    p = job.params
    for k in range(1, n):
        check_cancel()                  # between the stages (execution: a cancel reaches a running tile)
        x1, y1, x2, y2, info = match_pair_tile(job.images[0], job.images[k], job.models[0], job.models[k], box,
                                               job.height_range, p)
        nan = np.full(x2.size, np.nan, np.float32)
        q = (nan, nan, nan)
        if p.refine:
            check_cancel()
            rx, ry, *q = refine_positions(job.images[0], job.images[k], job.models[0], job.models[k], x1, y1, x2,
                                          y2, info["grid"].heights[::2], p.template, p.max_shift, p.robust)
            lone = isolated(x1, y1, np.isfinite(q[0]), p.step)      # they keep their dense positions
            rx[lone], ry[lone] = x2[lone], y2[lone]
            for v in q:
                v[lone] = np.nan
            x2, y2 = rx, ry
        positions.append((x2, y2))
        quality.append(q)
        info["refined"] = int(np.isfinite(q[0]).sum())
        infos.append(info)
    matched = np.array([np.isfinite(x2) for x2, _ in positions])
    keep = matched.any(axis=0)
    count = int(keep.sum())
    points = np.zeros(count, POINT_DTYPE)
    points["id"] = np.arange(1, count + 1)
    both = matched[:, keep].all(axis=0) & (n == 3)      # a pair's points are two-ray (group 1)
    points["group"] = np.where(both, 2, 1)
    flags = np.zeros(count, np.uint8)
    for k, bit in zip(range(n - 1), (COMB_A, COMB_B)):
        flags |= np.where(matched[k, keep], bit, 0).astype(np.uint8)
    points["flags"] = flags | DENSE
    for name in ("rho_c", "dx", "dy"):
        points[name] = np.nan
    points["rho_a"] = quality[0][0][keep]
    points["rho_b"] = quality[1][0][keep] if n == 3 else np.nan
    # rho_min: the smaller of the pairs' rho, NaN where a pair's position is the semi-global one (unrefined)
    rhos = np.array([q[0][keep] for q in quality])
    unrefined = (matched[:, keep] & ~np.isfinite(rhos)).any(axis=0)
    points["rho_min"] = np.where(unrefined, np.nan, np.where(np.isfinite(rhos), rhos, np.inf).min(axis=0))
    obs = [np.zeros(count, OBS_DTYPE)]
    obs[0]["point_id"], obs[0]["image_id"] = points["id"], job.image_ids[0]
    obs[0]["col"], obs[0]["row"], obs[0]["rho"] = x1[keep], y1[keep], np.nan
    for k, (x2, y2) in enumerate(positions, start=1):
        m = matched[k - 1, keep]
        o = np.zeros(int(m.sum()), OBS_DTYPE)
        o["point_id"], o["image_id"] = points["id"][m], job.image_ids[k]
        o["col"], o["row"] = x2[keep][m], y2[keep][m]
        o["rho"], o["semi_major"], o["semi_minor"] = (v[keep][m] for v in quality[k - 1])
        obs.append(o)
    obs = np.concatenate(obs)
    obs = obs[np.lexsort((obs["image_id"], obs["point_id"]))]
    return MultiPoints(points, obs), infos


def _dense_tile(job, box, out, quota):
    """Task, round 1: the tile's points to the work file `out`; returns its counts, and with DenseParams.mpgc
    the image positions of up to `quota` of its refined three-ray points (the orientation bias's sample)."""
    multi, infos = tile_points(job, box)
    save_array(out + ".points.npy", multi.points, "the matched tiles")
    save_array(out + ".observations.npy", multi.observations, "the matched tiles")
    three = np.flatnonzero((multi.points["group"] == 2) & np.isfinite(multi.points["rho_min"]))
    take = three[np.unique(np.linspace(0, three.size - 1, min(three.size, quota)).astype(int))] if three.size \
        else three
    sample = tuple(np.array(v)[:, take] for v in zip(*(multi.coordinates(i) for i in job.image_ids)))
    return {"points": len(multi), "group_2": int((multi.points["group"] == 2).sum()),
            "seeds": [i["seeds"] for i in infos], "row_offset": [i["row_offset"] for i in infos],
            "refined": sum(i["refined"] for i in infos), "sample": sample}


def _finish_tile(job, pre, first_id, k, folder):
    """Task, round 2: the work file's points numbered from first_id, their three-ray points refined by MPGC
    where job.bias is set (_mpgc), as the k-th part of `folder` (or returned without a write_part). Returns (the
    part, the points MPGC refined)."""
    multi = MultiPoints(np.load(pre + ".points.npy"), np.load(pre + ".observations.npy"))
    multi.points["id"] += first_id - 1
    multi.observations["point_id"] += first_id - 1
    check_cancel()
    refined = _mpgc(job, multi) if job.bias is not None else 0
    return (multi if job.write_part is None else job.write_part(folder, k, multi)), refined


def _mpgc(job, multi):
    """MPGC refinement of the three-ray points of `multi` in place (refinement.refine_three_ray with the scene's
    orientation bias, LSM's template and largest shift of DenseParams): a point MPGC accepts takes its search
    positions, correlations and error ellipses, the flag REFINED and rho_a, rho_b, rho_min from them (so it
    counts as refined even where the pairwise LSM had left a semi-global position). Returns the count."""
    p = job.params
    grow = GrowParams(template=p.template, max_shift=p.max_shift)
    count = refine_three_ray(multi, job.images, job.models, job.image_ids, job.height_range, grow, bias=job.bias,
                             group=2)
    done = np.flatnonzero(multi.points["flags"] & REFINED)
    if done.size:
        obs = multi.observations
        rho = []
        for image_id in job.image_ids[1:]:
            mine = obs[obs["image_id"] == image_id]
            values = np.full(len(multi.points), np.nan, np.float32)
            values[np.searchsorted(multi.points["id"], mine["point_id"])] = mine["rho"]
            rho.append(values[done])
        multi.points["rho_a"][done], multi.points["rho_b"][done] = rho
        multi.points["rho_min"][done] = np.minimum(*rho)
    return count


def match_dense_tiles(images, models, folder, write_part=None, names=None, image_ids=None, params=None,
                      height_range=None, feedback=None, execution=None):
    """Dense matching tile by tile (module docstring) of `images` (paths or arrays, opened masking their saturated
    pixels too; or Image-likes, read as they are): each tile's points handed to write_part(folder, k, points), or
    returned without it. Returns (the index entries or MultiPoints, in id order; stats). Raises InputError for
    other than 2 or 3 images, or where a pair has no epipolar geometry."""
    n = len(images)
    names, image_ids = block_inputs(images, models, names, image_ids, "dense matching")
    params = (params or DenseParams()).check()
    images = [as_image(image, saturation=True) for image in images]
    job = DenseJob(images, models, image_ids, params, height_range, write_part)
    tiles = tile_grid(models[0].size, params.tile)
    log = progress.ensure(feedback)
    log.pushInfo(f"dense matching: {len(tiles)} tile(s) of {params.tile} px, a point every {params.step} px of "
                 f"{names[0]}; pairs " + ", ".join(f"{names[0]} - {names[k]}" for k in range(1, n)))
    mpgc = params.mpgc and n == 3
    nodes = np.array([(b[1] - b[0]) * (b[3] - b[2]) for b in tiles], float)
    quotas = np.ceil(BIAS_SAMPLE * nodes / max(nodes.sum(), 1.0)).astype(int) if mpgc else np.zeros(len(tiles), int)
    with work_dir(folder, "the matched tiles") as work, session(execution):
        pre = [os.path.join(work, f"tile-{k:05d}") for k in range(len(tiles))]
        first = run_tasks(_dense_tile, [(job, box, out, int(q)) for box, out, q in zip(tiles, pre, quotas)],
                          execution, progress.scaled(feedback, 0, 80 if mpgc else 90), "dense matching")
        counts = [t["points"] for t in first]
        if mpgc:
            job = job._replace(bias=_scene_bias(job, first, feedback))
        done = run_tasks(_finish_tile, [(job, out, int(i), k, folder)
                                        for k, (out, i) in enumerate(zip(pre, first_ids(counts)))], execution,
                         progress.scaled(feedback, 80 if mpgc else 90, 100),
                         "MPGC and numbering the points" if job.bias is not None else "numbering the points")
        parts = [part for part, _ in done]
    empty = [k for k, c in enumerate(counts) if c == 0]
    if empty:
        progress.warn(feedback, f"{len(empty)} of {len(tiles)} tile(s) gave no point (no texture, no overlap, or "
                                f"nodata or saturated pixels only): tiles {', '.join(map(str, empty[:20]))}"
                                f"{' ...' if len(empty) > 20 else ''}")
    stats = {"images": image_ids, "strategy": "dense", "points": int(sum(counts)),
             "group_2": int(sum(t["group_2"] for t in first)),
             "seeds": int(sum(sum(t["seeds"]) for t in first)), "refined": int(sum(t["refined"] for t in first))}
    if job.bias is not None:
        stats["refined_mpgc"] = int(sum(r for _, r in done))
    log.pushInfo(f"dense matching: {stats['points']} points"
                 + (f", {stats['group_2']} of them in three images" if n == 3 else "")
                 + (f"; {stats['refined']} image positions refined by LSM" if params.refine else "")
                 + (f"; {stats['refined_mpgc']} three-ray points refined by MPGC" if job.bias is not None else ""))
    return parts, stats


def _scene_bias(job, first, feedback):
    """(corrected models, systematic px) of orientation_bias.affine_bias fitted to the sampled refined three-ray
    points of round 1, or None (and a warning) for fewer than refinement.MIN_POINTS."""
    cols, rows = (np.concatenate([t["sample"][i] for t in first], axis=-1) for i in range(2))
    if cols.shape[-1] < MIN_POINTS:
        progress.warn(feedback, f"MPGC needs at least {MIN_POINTS} refined three-ray points to fit the orientation's "
                                f"bias; the dense matching has {cols.shape[-1]}: the points keep their pairwise LSM "
                                "positions")
        return None
    corrected, _, systematic = affine_bias(job.models, cols, rows)
    return corrected, systematic
