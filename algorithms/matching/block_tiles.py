"""The three combinations of Kornus et al. 2006, section 3.3 (combinations.py) tile by tile, so that
memory follows the tile and the number of workers, not the scene.

The tiles are region growing's tiles of the reference image (region_growing.grow_job: the same for
combinations (a) and (b)). Each tile is a task on the chosen execution (execution.run_tasks), in two
rounds:

1. `_match_tile`: (a) grown in the tile; (b) grown in the tile where asked; (a)'s points transferred
   into image 2 (guided by the tile's (b) points), (b)'s own points added where (a) has none; (b)'s
   points transferred into image 1 (c); combined (combinations.combine) without the consistency
   test, written to a work file with the deviations dx, dy of its group 3 candidates. It returns their
   histograms of |dx| and |dy| (histogram.py, DEVIATION_STEP bins: what travels back does not grow with
   the points) and a sample of their image positions (BIAS_SAMPLE over the scene, in proportion to the
   tile's lattice nodes).
2. The consistency test's robust sigmas, 1.4826 median(|d|), come from the sum of all tiles' histograms
   (as for the whole scene, to within a bin), so every tile keeps the points the whole scene would; a
   short round (`_kept`) counts each tile's points that pass, so that its point ids can be numbered on
   from the tiles before it. MPGC's affine image biases and geometry sigma
   (orientation_bias.affine_bias) are fitted to the sample's points that pass the test: one
   orientation for the scene, as when it is matched at once (which fits them to all its points; the
   refinement needs MIN_POINTS of them in the scene). `_finish_tile` applies the test, numbers the
   points, refines its group 3 points by MPGC with that orientation (refinement.refine_three_ray) and
   hands them to `write_part` (the step passes block/points.save_part, which writes them as a part of
   the new sidecar folder), or returns them.

The work files of round 1 (two .npy arrays per tile) lie in a work folder beside the sidecar folder
(atomic.work_dir), where every worker sees them.

What differs from matching the scene at once: a transfer point takes its initial values from its own
tile's points, and MPGC's biases come from a sample of the points. The result does not depend on the
execution or the number of workers."""
import os
from typing import NamedTuple

import numpy as np

from .. import histogram, progress
from ..atomic import save_array, work_dir
from ..errors import InputError
from ..execution import run_tasks, session
from ..stats import NMAD_SCALE
from ..task_runtime import check_cancel
from .combinations import combine, compose_guide, new_cells, pair_seeds
from .orientation_bias import affine_bias
from .params import GrowParams
from .points import MultiPoints
from .records import PAIR_DTYPE
from .refinement import MIN_POINTS, refine_three_ray
from .region_growing import _grow_tile, grow_job, transfer_points

#: floor of the consistency test's robust sigmas (px), as combinations.combine's
MIN_SIGMA = 0.01
#: bin of the deviation histograms (px) the tiles return
DEVIATION_STEP = 1e-4
#: group 3 points of the scene that MPGC's affine biases are fitted to
BIAS_SAMPLE = 50_000
#: counts of combinations.combine's stats that add up over the tiles
ADDED = ("matched_a", "matched_b", "matched_c", "transfer_b", "own_b", "matched_3")


class TileJob(NamedTuple):
    """What every tile of a block shares (module docstring)."""

    images: list
    models: list
    image_ids: list
    params: GrowParams
    height_range: object    # as given (the pair functions resolve it per model, as match_block always did)
    grow_a: object          # region_growing.GrowJob of (a)
    grow_b: object          # of (b), or None where (b) is not grown
    refine: bool            # round 2: with the scene's MPGC orientation `bias`
    bias: object            # (corrected models, systematic px) of orientation_bias.affine_bias, or None
    write_part: object      # write_part(folder, k, MultiPoints) -> index entry, a module-level function; or None


def _transfer(image1, image2, model1, model2, x1, y1, params, hr, guide):
    """region_growing.transfer_points, for no points too."""
    if len(x1) == 0:
        return np.zeros(0, PAIR_DTYPE), np.zeros(0, bool)
    return transfer_points(image1, image2, model1, model2, x1, y1, params, hr,
                           guide=guide if guide is not None and len(guide) else None)


def _save_work(path, multi):
    save_array(path + ".points.npy", multi.points, "the matched tiles")
    save_array(path + ".observations.npy", multi.observations, "the matched tiles")


def _load_work(path):
    return MultiPoints(np.load(path + ".points.npy"), np.load(path + ".observations.npy"))


def _match_tile(job, index, box, out, quota):
    """Task, round 1 (module docstring): the tile `box` (the index-th of Lattice.tiles) combined without
    the consistency test, written to `out`. Returns its counts, the histograms of |dx|, |dy| of its group 3
    candidates and the image positions and deviations of up to `quota` of them."""
    images, models, ids, params, hr = job.images, job.models, job.image_ids, job.params, job.height_range
    a, tries, seeds = _grow_tile(job.grow_a, index, box)
    check_cancel()                      # between the combinations (execution: a cancel reaches a running tile)
    if len(images) == 2:
        multi = combine(a, image_ids=ids)
        dx = dy = np.full(len(multi), np.nan)
    else:
        grown = _grow_tile(job.grow_b, index, box)[0] if job.grow_b is not None else None
        check_cancel()
        bt, ok = _transfer(images[0], images[2], models[0], models[2], a["x1"], a["y1"], params, hr, grown)
        b, b_src = bt[ok], np.flatnonzero(ok)
        b["x1"], b["y1"] = a["x1"][b_src], a["y1"][b_src]        # transfer points keep image 0 exactly
        if grown is not None:
            fresh = grown[new_cells(grown["x1"], grown["y1"], a["x1"], a["y1"], params.step)]
            b = np.concatenate([b, fresh])
            b_src = np.concatenate([b_src, np.full(len(fresh), -1)])
        check_cancel()
        ct, ok = _transfer(images[2], images[1], models[2], models[1], b["x2"], b["y2"], params, hr,
                           compose_guide(a, b, b_src))
        c, c_src = ct[ok], np.flatnonzero(ok)
        c["x1"], c["y1"] = b["x2"][c_src], b["y2"][c_src]
        multi, dx, dy = combine(a, b, b_src, c, c_src, image_ids=ids, sigma_factor=np.inf, deviations=True)
    _save_work(out, multi)
    save_array(out + ".deviations.npy", np.column_stack([dx, dy]), "the matched tiles")
    both = np.flatnonzero(np.isfinite(dx))
    take = both[np.unique(np.linspace(0, len(both) - 1, min(len(both), quota)).astype(int))] if len(both) else both
    cols, rows = (np.array(v)[:, take] for v in zip(*(multi.coordinates(i) for i in ids)))
    return {"points": len(multi), **{k: histogram.count(np.round(np.abs(d[both]) / DEVIATION_STEP))
                                     for k, d in (("dx", dx), ("dy", dy))},
            "sample": (cols, rows, dx[take], dy[take]),
            "tries": tries, "seeds": seeds, **{k: multi.stats.get(k, 0) for k in ADDED}}


def _passes(dx, dy, limits):
    """The points that pass the consistency test: |dx| < limits[0] and |dy| < limits[1] where both are defined."""
    return ~np.isfinite(dx) | ((np.abs(dx) < limits[0]) & (np.abs(dy) < limits[1]))


def _kept(pre, limits):
    """Task, between the rounds: how many points of the work file `pre` pass the consistency test."""
    return int(np.count_nonzero(_passes(*np.load(pre + ".deviations.npy").T, limits)))


def _robust_sigma(hists):
    """1.4826 median(|d|) of the deviations whose |d| histograms are `hists`, at least MIN_SIGMA."""
    bins, counts = histogram.total(hists)
    return max(NMAD_SCALE * histogram.median(bins * DEVIATION_STEP, counts), MIN_SIGMA) if counts.sum() else MIN_SIGMA


def _finish_tile(job, pre, limits, first_id, k, folder):
    """Task, round 2 (module docstring): the points of the work file `pre` that pass the consistency test
    (|dx| < limits[0] and |dy| < limits[1] where both are defined), numbered from `first_id`, refined by
    MPGC where asked, handed to job.write_part as the k-th part of the sidecar folder `folder`. Returns
    (its index entry, or the MultiPoints without a write_part; MPGC's stats)."""
    multi = _load_work(pre)
    p = multi.points
    keep = _passes(*np.load(pre + ".deviations.npy").T, limits)
    points, obs = p[keep], multi.observations
    obs = obs[np.isin(obs["point_id"], points["id"])]
    new_id = np.zeros(len(p) + 1, np.int64)
    new_id[points["id"]] = first_id + np.arange(len(points))
    points["id"], obs["point_id"] = new_id[points["id"]], new_id[obs["point_id"]]
    multi = MultiPoints(points, obs, {})
    if job.refine and job.bias is not None:
        check_cancel()
        refine_three_ray(multi, job.images, job.models, job.image_ids, job.height_range, job.params, bias=job.bias)
    return (multi if job.write_part is None else job.write_part(folder, k, multi)), multi.stats


def _scene_bias(job, first, limits):
    """(corrected models, systematic px) of orientation_bias.affine_bias fitted to the sampled group 3
    points of the tiles (round 1) that pass the consistency test; None for fewer than MIN_POINTS."""
    cols, rows, dx, dy = (np.concatenate([t["sample"][i] for t in first], axis=-1) for i in range(4))
    keep = (np.abs(dx) < limits[0]) & (np.abs(dy) < limits[1])
    if keep.sum() < MIN_POINTS:
        return None
    corrected, _, systematic = affine_bias(job.models, cols[:, keep], rows[:, keep])
    return corrected, systematic


def block_inputs(images, models, names, image_ids, what):
    """(names, image ids) of a pair or triplet matched tile by tile (defaults "image k", 1 ... n); InputError
    for other than 2 or 3 images with a model each (`what`: the matcher, for the message)."""
    n = len(images)
    if n not in (2, 3) or len(models) != n:
        raise InputError(f"{what} takes 2 or 3 images (reference, forward[, backward]), got {n}")
    return list(names or [f"image {k + 1}" for k in range(n)]), list(image_ids or range(1, n + 1))


def first_ids(counts):
    """The first point id of each tile whose points number `counts`, so that ids run 1 ... N in tile order."""
    return np.concatenate([[1], 1 + np.cumsum(counts)[:-1]]).astype(int) if len(counts) else []


def match_tiles(images, models, folder, write_part=None, names=None, image_ids=None, params=None, height_range=None,
                seed_points=None, automatic=True, feedback=None, execution=None, grow_second=True, sigma_factor=3.0,
                refine=True):
    """combinations.match_block tile by tile (module docstring): each tile's points handed to
    `write_part(folder, k, points)` (a module-level function: block/points.save_part), or, without it,
    returned. Returns (the index entries or MultiPoints of the tiles, in id order; stats). The work
    folder lies beside `folder`. Raises what match_block raises."""
    n = len(images)
    names, image_ids = block_inputs(images, models, names, image_ids, "matching")
    params = (params or GrowParams()).check()
    log = progress.ensure(feedback)
    if seed_points is None and not automatic:
        raise InputError("region growing needs seeds: give seed points or allow automatic seeds")

    def seeds(k):
        if seed_points is None:
            return None
        found = pair_seeds(images[0], images[k], models[0], models[k], seed_points, image_ids[0], image_ids[k],
                           params, height_range)
        log.pushInfo(f"{names[0]} - {names[k]}: {len(found)} seeds from the given points")
        return found

    grow_a, tiles = grow_job(images[0], images[1], models[0], models[1], params, height_range, seeds(1), automatic)
    grow_b = None
    if n == 3 and grow_second:
        grow_b = grow_job(images[0], images[2], models[0], models[2], params, height_range, seeds(2), automatic)[0]
    job = TileJob(images, models, image_ids, params, height_range, grow_a, grow_b, refine and n == 3, None, write_part)
    nodes = np.array([(n_b - n_a) * (m_b - m_a) for n_a, n_b, m_a, m_b in tiles], float)
    quotas = np.ceil(BIAS_SAMPLE * nodes / max(nodes.sum(), 1.0)).astype(int)
    log.pushInfo(f"{len(tiles)} tile(s) of {params.tile} px: " + (f"(a) {names[0]} - {names[1]}" if n == 2 else
                 f"(a) {names[0]} - {names[1]}, (b) {names[0]} - {names[2]}, (c) {names[2]} - {names[1]}"))
    with work_dir(folder, "the matched tiles") as work, session(execution):     # the rounds share workers
        pre = [os.path.join(work, f"tile-{k:05d}") for k in range(len(tiles))]
        first = run_tasks(_match_tile, [(job, k, box, out, int(q)) for k, (box, out, q)
                                        in enumerate(zip(tiles, pre, quotas))],
                          execution, progress.scaled(feedback, 0, 75), "matching")
        sigmas = (_robust_sigma(t["dx"] for t in first), _robust_sigma(t["dy"] for t in first))
        limits = (sigma_factor * sigmas[0], sigma_factor * sigmas[1])
        candidates = int(sum(t["dx"][1].sum() for t in first))
        kept = run_tasks(_kept, [(out, limits) for out in pre], execution, progress.scaled(feedback, 75, 75),
                         "the consistency test's counts")
        ids = first_ids(kept)
        job = job._replace(bias=_scene_bias(job, first, limits) if job.refine else None)
        second = run_tasks(_finish_tile, [(job, out, limits, int(i), k, folder)
                                          for k, (out, i) in enumerate(zip(pre, ids))],
                           execution, progress.scaled(feedback, 75, 100), "the consistency test and MPGC")
    stats = {"images": image_ids if n == 3 else image_ids[:2], **{k: int(sum(t[k] for t in first)) for k in ADDED},
             "rejected_3sigma": int(sum(t["points"] for t in first) - sum(kept)),
             "sigma_dx": sigmas[0] if candidates else None, "sigma_dy": sigmas[1] if candidates else None,
             "sigma_factor": float(sigma_factor)}
    if job.bias is not None:
        refined = [s for _, s in second if "refined_mpgc" in s]
        stats["refined_mpgc"] = int(sum(s["refined_mpgc"] for s in refined))
        if refined:         # the scene's orientation: the same in every tile
            stats.update({k: refined[0][k] for k in ("refine_sigma_geometry_px", "refine_bias_px")})
    points, tries, nseeds = sum(kept), sum(t["tries"] for t in first), sum(t["seeds"] for t in first)
    if stats["matched_a"] == 0:
        progress.warn(feedback, "region growing found no matched point: no seed passed the acceptance criteria "
                                f"({nseeds} seed(s) in {len(tiles)} tile(s)); check the image pair, the height range "
                                "and the texture, or give seeds")
    log.pushInfo(f"region growing (a): {stats['matched_a']} points of {tries} LSM attempts from {nseeds} seed(s); "
                 f"{points} points kept" + (f", {stats['rejected_3sigma']} failed the consistency test"
                                             if n == 3 else ""))
    return [part for part, _ in second], stats
