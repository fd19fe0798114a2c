"""Dense matching, the third matching strategy: a pair or a triplet tile by tile in the two rounds of
matching/tiled_rounds.py, into the same point parts as region growing (matching/points.py's MultiPoints,
block/points.write_part), so that the rest of the chain reads them unchanged.

The tiles are the reference image's (tiling.tile_grid of DenseParams.tile px).
1. `match_tile`: for each pair (reference, forward) and, for a triplet, (reference, backward), the lattice
   nodes' image-2 positions (pair_tile.match_pair_tile); a node becomes a point where one pair matched it (group
   1, two rays) or both did (group 2, three rays from the two combinations; flags COMB_A, COMB_B as region
   growing's). With DenseParams.mpgc, a sample of its refined three-ray points' positions.
2. `between`: with DenseParams.mpgc, the scene's orientation bias fitted to the tiles' samples.
3. Round 2: the points numbered on from the tiles before, their three-ray points refined by MPGC with that
   orientation (`_mpgc`).

Observations: the reference image's position is the lattice node (rho NaN, axes 0: the template, as region
growing's); a matched image's position carries LSM's rho and error-ellipse semi-axes where the refinement
(refine.py) replaced it, NaN where it stayed the semi-global matcher's; where the bias test (refine.biased) found
LSM's moves systematic in either pair, the node's refined positions go back to the semi-global ones, with LSM's rho
(LSM's template correlates there, at its own position up to the largest shift away) and the semi-global precision's
axes (precision.SEMI_GLOBAL_AXIS), and the point is flagged SEMI_GLOBAL: it counts as measured in the DEM's tiers
and in tie point selection (by that rho), MPGC leaves it and its orientation sample skips it. A point's rho_a /
rho_b are its pairs' LSM rho; rho_min the smaller, NaN where one of its matched positions is unrefined (a point is
"refined" only if all of them are: the DEM's tiers and the tie point selection read it); flags DENSE. A tile without
texture gives no points and a warning, not an error.

The images are opened once, masking their nodata (the band's value and GDAL mask) and saturated pixels
(matching.imagery.Image, saturation=True): a node whose census window or LSM template reaches a masked pixel,
or whose candidate conjugates do, yields no point (pair_tile.py, refine.py).

The result does not depend on the execution or the number of workers: a tile's points depend only on its box."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from .. import progress
from ..execution import Execution
from ..height_range import GivenHeights
from ..matching.imagery import as_image
from ..matching.match_stats import MatchStats
from ..matching.pair_geometry import ImagePair
from ..matching.params import GrowParams
from ..matching.points import COMB_A, COMB_B, DENSE, OBS_DTYPE, POINT_DTYPE, REFINED, SEMI_GLOBAL, MultiPoints
from ..matching.refinement import MIN_POINTS, refine_three_ray
from ..matching.stereo_set import StereoSet
from ..matching.strategy import MatchingStrategy, RoundResults, Rounds, TilePlan, register
from ..matching.tiled_rounds import evenly, match_in_tiles, positions, sample_quotas, save_work, scene_bias
from ..progress import Feedback
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .pair_tile import match_pair_tile
from .params import DenseParams
from .precision import SEMI_GLOBAL_AXIS
from .refine import Conjugates, lattice_tests, refine_positions

#: a tile of the reference image: (x0, y0, x1, y1) px, tiling.tile_grid's
Box = tuple[int, int, int, int]


class DenseJob(NamedTuple):
    """What every tile shares: the set (its images opened masking saturated pixels), the settings, and with
    DenseParams.mpgc the scene's orientation bias (tiled_rounds.scene_bias) once fitted."""

    stereo: StereoSet
    params: DenseParams
    bias: tuple[Any, float] | None = None


def tile_points(job: DenseJob, box: Box) -> tuple[MultiPoints, list[dict[str, Any]]]:
    """The MultiPoints of one tile (ids 1 ... n in lattice order) and its per-pair information."""
    s = job.stereo
    n = len(s)
    positions, quality, infos, dense, kept = [], [], [], [], []
    p = job.params
    for k in range(1, n):
        check_cancel()  # between the stages (execution: a cancel reaches a running tile)
        x1, y1, x2, y2, info = match_pair_tile(
            s.images[0], s.images[k], s.models[0], s.models[k], box, s.heights.bounds, p
        )
        nan = np.full(x2.size, np.nan, np.float32)
        q = (nan, nan, nan)
        dense.append((x2, y2))
        if p.lsm:
            check_cancel()
            conjugates = Conjugates(x1, y1, x2, y2)
            pair = ImagePair(s.images[0], s.images[k], s.models[0], s.models[k])
            r, found = lattice_tests(
                conjugates,
                refine_positions(pair, conjugates, info["grid"].heights[::2], p.refinement()),
                info["grid"],
                p,
            )
            kept.append(found)
            x2, y2, q = r.x2, r.y2, (r.rho, r.semi_major, r.semi_minor)
        positions.append((x2, y2))
        quality.append(q)
        info["refined"] = int(np.isfinite(q[0]).sum())
        infos.append(info)
    # the test's finding is the reference template's (both pairs' LSM share it): every refined position of a node
    # one pair found biased keeps its semi-global position, measured
    either = np.any(kept, axis=0) if kept else np.zeros(positions[0][0].size, bool)
    for (x2, y2), (sx, sy), q, info in zip(positions, dense, quality, infos):
        at = either & np.isfinite(q[0])
        x2[at], y2[at] = sx[at], sy[at]
        q[1][at] = q[2][at] = SEMI_GLOBAL_AXIS
        info["semi_global"] = int(at.sum())
    matched = np.array([np.isfinite(x2) for x2, _ in positions])
    keep = matched.any(axis=0)
    count = int(keep.sum())
    points = np.zeros(count, POINT_DTYPE)
    points["id"] = np.arange(1, count + 1)
    both = matched[:, keep].all(axis=0) & (n == 3)  # a pair's points are two-ray (group 1)
    points["group"] = np.where(both, 2, 1)
    flags = np.zeros(count, np.uint8)
    for k, bit in zip(range(n - 1), (COMB_A, COMB_B)):
        flags |= np.where(matched[k, keep], bit, 0).astype(np.uint8)
    points["flags"] = flags | DENSE | np.where(either[keep], SEMI_GLOBAL, 0).astype(np.uint8)
    for name in ("rho_c", "dx", "dy"):
        points[name] = np.nan
    points["rho_a"] = quality[0][0][keep]
    points["rho_b"] = quality[1][0][keep] if n == 3 else np.nan
    # rho_min: the smaller of the pairs' rho, NaN where a pair's position is the semi-global one (unrefined)
    rhos = np.array([q[0][keep] for q in quality])
    unrefined = (matched[:, keep] & ~np.isfinite(rhos)).any(axis=0)
    points["rho_min"] = np.where(unrefined, np.nan, np.where(np.isfinite(rhos), rhos, np.inf).min(axis=0))
    obs = [np.zeros(count, OBS_DTYPE)]
    obs[0]["point_id"], obs[0]["image_id"] = points["id"], s.ids[0]
    obs[0]["col"], obs[0]["row"], obs[0]["rho"] = x1[keep], y1[keep], np.nan
    for k, (x2, y2) in enumerate(positions, start=1):
        m = matched[k - 1, keep]
        o = np.zeros(int(m.sum()), OBS_DTYPE)
        o["point_id"], o["image_id"] = points["id"][m], s.ids[k]
        o["col"], o["row"] = x2[keep][m], y2[keep][m]
        o["rho"], o["semi_major"], o["semi_minor"] = (v[keep][m] for v in quality[k - 1])
        obs.append(o)
    merged = np.concatenate(obs)
    return MultiPoints(points, merged[np.lexsort((merged["image_id"], merged["point_id"]))]), infos


@register
class Dense(MatchingStrategy):
    """Semi-global matching of every pixel (or every DenseParams.step px) on epipolar tiles, refined by LSM."""

    name = "dense"
    settings_type = DenseParams
    spacing_setting = "step"
    first_round = "dense matching"

    @classmethod
    def plan(cls, stereo: StereoSet, settings: DenseParams, feedback: Feedback | None) -> TilePlan:
        s = dataclasses.replace(
            stereo.without_loader(), images=tuple(as_image(image, saturation=True) for image in stereo.images)
        )
        tiles = tile_grid(s.models[0].size, settings.tile)
        progress.ensure(feedback).pushInfo(
            f"dense matching: {len(tiles)} tile(s) of {settings.tile} px, a point every {settings.step} px of "
            f"{s.names[0]}; pairs " + ", ".join(f"{s.names[0]} - {s.names[k]}" for k in range(1, len(s)))
        )
        mpgc = settings.mpgc and s.triplet
        quotas = sample_quotas([(x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in tiles]) if mpgc else [0] * len(tiles)
        return TilePlan(DenseJob(s, settings), tiles, quotas)

    @staticmethod
    def match_tile(job: DenseJob, index: int, box: Box, out: str, quota: int) -> dict[str, Any]:
        """Round 1: the tile's points to the work file `out`; its counts, and the image positions of up to `quota`
        of its refined three-ray points (the orientation bias's sample)."""
        multi, infos = tile_points(job, box)
        save_work(out, multi)
        pts = multi.points
        three = np.flatnonzero((pts["group"] == 2) & np.isfinite(pts["rho_min"]) & (pts["flags"] & SEMI_GLOBAL == 0))
        return {
            "points": len(multi),
            "group_2": int((multi.points["group"] == 2).sum()),
            "seeds": [i["seeds"] for i in infos],
            "row_offset": [i["row_offset"] for i in infos],
            "refined": sum(i["refined"] for i in infos),
            "semi_global": sum(i["semi_global"] for i in infos),
            "sample": positions(multi, job.stereo.ids, evenly(three, quota)),
        }

    @classmethod
    def between(
        cls, job: DenseJob, first: list[dict[str, Any]], outs: list[str], rounds: Rounds, feedback: Feedback | None
    ) -> tuple[DenseJob, list[int]]:
        """The scene's orientation bias where MPGC refines (None and a warning for too few points)."""
        counts = [int(t["points"]) for t in first]
        if not (job.params.mpgc and job.stereo.triplet):
            return job, counts
        cols, rows = (np.concatenate([t["sample"][i] for t in first], axis=-1) for i in range(2))
        bias = scene_bias(job.stereo.models, cols, rows)
        if bias is None:
            progress.warn(
                feedback,
                f"MPGC needs at least {MIN_POINTS} refined three-ray points to fit the "
                f"orientation's bias; the dense matching has {cols.shape[-1]}: the points keep "
                "their pairwise LSM positions",
            )
        return job._replace(bias=bias), counts

    @staticmethod
    def refine(job: DenseJob, points: MultiPoints) -> dict[str, Any]:
        check_cancel()
        return {"refined_mpgc": _mpgc(job, points)} if job.bias is not None else {}

    @classmethod
    def stats(cls, job: DenseJob, rounds: RoundResults, feedback: Feedback | None) -> MatchStats:
        first, refined, counts = rounds
        s, p = job.stereo, job.params
        empty = [k for k, t in enumerate(first) if t["points"] == 0]
        if empty:
            progress.warn(
                feedback,
                f"{len(empty)} of {len(first)} tile(s) gave no point (no texture, no overlap, "
                f"or nodata or saturated pixels only): tiles {', '.join(map(str, empty[:20]))}"
                f"{' ...' if len(empty) > 20 else ''}",
            )
        stats = MatchStats(
            cls.name,
            list(s.ids),
            int(sum(counts)),
            details={
                "group_2": int(sum(t["group_2"] for t in first)),
                "seeds": int(sum(sum(t["seeds"]) for t in first)),
                "refined": int(sum(t["refined"] for t in first)),
                "semi_global": int(sum(t["semi_global"] for t in first)),
            },
        )
        if job.bias is not None:
            stats.refined_mpgc = int(sum(r.get("refined_mpgc", 0) for r in refined))
        d = stats.details
        progress.ensure(feedback).pushInfo(
            f"dense matching: {stats.points} points"
            + (f", {d['group_2']} of them in three images" if s.triplet else "")
            + (
                f"; {d['refined']} image positions measured by LSM, {d['semi_global']} of them kept at their "
                "semi-global position by the bias test"
                if p.lsm
                else ""
            )
            + (f"; {stats.refined_mpgc} three-ray points refined by MPGC" if job.bias is not None else "")
        )
        return stats


def _mpgc(job: DenseJob, multi: MultiPoints) -> int:
    """MPGC refinement of the three-ray points of `multi` in place (refinement.refine_three_ray with the scene's
    orientation bias, LSM's template and largest shift of DenseParams; not the points whose positions the bias
    test kept semi-global, where MPGC's templates straddle the same heights): a point MPGC accepts takes its search
    positions, correlations and error ellipses, the flag REFINED and rho_a, rho_b, rho_min from them (so it
    counts as refined even where the pairwise LSM had left a semi-global position). Returns the count."""
    p, s = job.params, job.stereo
    grow = GrowParams(template=p.template, max_shift=p.max_shift)
    kept = (multi.points["flags"] & SEMI_GLOBAL) != 0
    count = refine_three_ray(multi, s, grow, bias=job.bias, group=2, exclude=kept)
    done = np.flatnonzero(multi.points["flags"] & REFINED)
    if done.size:
        obs = multi.observations
        rho = []
        for image_id in s.ids[1:]:
            mine = obs[obs["image_id"] == image_id]
            values = np.full(len(multi.points), np.nan, np.float32)
            values[np.searchsorted(multi.points["id"], mine["point_id"])] = mine["rho"]
            rho.append(values[done])
        multi.points["rho_a"][done], multi.points["rho_b"][done] = rho
        multi.points["rho_min"][done] = np.minimum(*rho)
    return count


def match_dense_tiles(
    images: Sequence[Any],
    models: Sequence[Any],
    folder: str,
    params: DenseParams | None = None,
    height_range: GivenHeights = None,
    execution: Execution | None = None,
    names: Sequence[str] | None = None,
    feedback: Feedback | None = None,
) -> tuple[list[MultiPoints], dict[str, Any]]:
    """Dense matching (module docstring) of 2 or 3 `images` (paths or arrays, opened masking their saturated pixels
    too; or Image-likes) with their sensor models, block ids 1 ... n, its work folder beside `folder`: (the tiles'
    MultiPoints in id order, the stats as a dict). Raises InputError for other than 2 or 3 images, or where a
    pair has no epipolar geometry."""
    parts, stats = match_in_tiles(
        Dense, StereoSet.of(images, models, names, heights=height_range), params, folder, None, execution, feedback
    )
    return parts, stats.as_dict()
