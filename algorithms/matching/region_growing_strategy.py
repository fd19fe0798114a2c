"""Region growing, the first matching strategy: the three combinations of Kornus et al. 2006, section 3.3
(three_combinations.py), tile by tile in the two rounds of tiled_rounds.py.

The tiles are region growing's tiles of the reference image (region_growing.grow_job: the same for
combinations (a) and (b)).

1. `match_tile`: (a) grown in the tile; (b) grown in the tile where asked; (a)'s points transferred into
   image 2 (guided by the tile's (b) points), (b)'s own points added where (a) has none; (b)'s points
   transferred into image 1 (c); combined (three_combinations.combine) without the consistency test, written to
   a work file with the deviations dx, dy of its group 3 candidates. It returns their histograms of |dx| and
   |dy| (histogram.py, DEVIATION_STEP bins: what travels back does not grow with the points) and a sample of
   their image positions (tiled_rounds.BIAS_SAMPLE over the scene, in proportion to the tile's lattice nodes).
2. `between`: the consistency test's robust sigmas, 1.4826 median(|d|), come from the sum of all tiles'
   histograms (as for the whole scene, to within a bin), so every tile keeps the points the whole scene would; a
   short round (`_kept`) counts each tile's points that pass, so that its point ids can be numbered on from the
   tiles before it. MPGC's affine image biases and geometry sigma (orientation_bias.affine_bias) are fitted to
   the sample's points that pass the test: one orientation for the scene, as when it is matched at once (the
   refinement needs refinement.MIN_POINTS of them in the scene).
3. Round 2 keeps the points that pass the test and refines their group 3 points by MPGC with that orientation
   (refinement.refine_three_ray).

Seeds: automatic ones in every tile, and/or the block's tie points seen in the reference and the other image of
a region-grown pair, re-matched there (`pair_seeds`).

What differs from matching the scene at once: a transfer point takes its initial values from its own tile's
points, and MPGC's biases come from a sample of the points. The result does not depend on the execution or the
number of workers."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from .. import histogram, progress
from ..atomic import save_array
from ..errors import InputError
from ..execution import Execution
from ..height_range import GivenHeights
from ..progress import Feedback
from ..stats import NMAD_SCALE
from ..task_runtime import check_cancel
from .match_stats import MatchStats
from .pair_geometry import ImagePair
from .params import GrowParams
from .points import MultiPoints
from .records import PAIR_DTYPE
from .refinement import refine_three_ray
from .region_growing import GrowJob, _grow_tile, grow_job, transfer_points
from .stereo_set import StereoSet
from .strategy import MatchingStrategy, RoundResults, Rounds, TilePlan, register
from .three_combinations import Transfer, combine, compose_guide, new_cells
from .tiled_rounds import evenly, match_in_memory, positions, sample_quotas, save_work, scene_bias

#: seed sources: key -> (use the block's tie points, seek automatic seeds)
SEED_SOURCES = {"automatic": (False, True), "tie_points": (True, False), "both": (True, True)}
#: floor of the consistency test's robust sigmas (px), as three_combinations.combine's
MIN_SIGMA = 0.01
#: bin of the deviation histograms (px) the tiles return
DEVIATION_STEP = 1e-4
#: counts of three_combinations.combine's stats that add up over the tiles
ADDED = ("matched_a", "matched_b", "matched_c", "transfer_b", "own_b", "matched_3")


@dataclass
class RegionGrowingSettings:
    """grow: LSM and the lattice (STEP, tiles); seeds: one of SEED_SOURCES; sigma_factor: the group 3 consistency
    test keeps deviations below this many robust sigmas; grow_second: also grow combination (b) where (a) found
    no points; mpgc: MPGC refinement of the group 3 points (three images)."""

    grow: GrowParams = field(default_factory=GrowParams)
    seeds: str = "automatic"
    sigma_factor: float = 3.0
    grow_second: bool = True
    mpgc: bool = True

    def check(self) -> RegionGrowingSettings:
        """Raise InputError for settings region growing cannot use."""
        if self.seeds not in SEED_SOURCES:
            raise InputError(f"the seeds must be one of {', '.join(SEED_SOURCES)}, got {self.seeds!r}")
        if self.sigma_factor <= 0:
            raise InputError("the consistency factor must be positive")
        self.grow.check()
        return self


class TileJob(NamedTuple):
    """What every tile of a run shares."""

    stereo: StereoSet
    settings: RegionGrowingSettings
    grow_a: GrowJob  # of (a)
    grow_b: GrowJob | None  # of (b), or None where (b) is not grown
    mpgc: bool  # round 2: MPGC with the scene's orientation `bias`
    limits: tuple[float, float] = (np.inf, np.inf)  # the consistency test's |dx|, |dy| limits (px)
    sigmas: tuple[float, float] = (MIN_SIGMA, MIN_SIGMA)
    bias: tuple[Any, float] | None = None  # tiled_rounds.scene_bias, or None


def pair_seeds(stereo: StereoSet, k: int, seed_points: MultiPoints, params: GrowParams) -> np.ndarray:
    """PAIR_DTYPE seeds of the pair (reference, image k) from the points of `seed_points` observed in both: each is
    re-matched from its stored image-k position on the images the growth uses (region_growing.transfer_points)
    and kept if it passes the acceptance criteria."""
    x1, y1 = seed_points.coordinates(stereo.ids[0])
    x2, y2 = seed_points.coordinates(stereo.ids[k])
    both = np.isfinite(x1) & np.isfinite(y1) & np.isfinite(x2) & np.isfinite(y2)
    if not both.any():
        return np.zeros(0, PAIR_DTYPE)
    recs, ok = transfer_points(
        ImagePair(stereo.images[0], stereo.images[k], stereo.models[0], stereo.models[k]),
        x1[both],
        y1[both],
        params,
        stereo.heights.bounds,
        x2=x2[both],
        y2=y2[both],
    )
    return recs[ok]


def _transfer(
    job: TileJob, pair: tuple[int, int], x1: np.ndarray, y1: np.ndarray, guide: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """region_growing.transfer_points of the image pair `pair` (indices into the set), for no points too."""
    if len(x1) == 0:
        return np.zeros(0, PAIR_DTYPE), np.zeros(0, bool)
    s, (i, j) = job.stereo, pair
    return transfer_points(
        ImagePair(s.images[i], s.images[j], s.models[i], s.models[j]),
        x1,
        y1,
        job.settings.grow,
        s.heights.bounds,
        guide=guide if guide is not None and len(guide) else None,
    )


def _passes(dx: np.ndarray, dy: np.ndarray, limits: tuple[float, float]) -> np.ndarray:
    """The points that pass the consistency test: |dx| < limits[0] and |dy| < limits[1] where both are defined."""
    return ~np.isfinite(dx) | ((np.abs(dx) < limits[0]) & (np.abs(dy) < limits[1]))


def _kept(out: str, limits: tuple[float, float]) -> int:
    """Task, between the rounds: how many points of the work file `out` pass the consistency test."""
    return int(np.count_nonzero(_passes(*np.load(out + ".deviations.npy").T, limits)))


def _robust_sigma(hists: Any) -> float:
    """1.4826 median(|d|) of the deviations whose |d| histograms are `hists`, at least MIN_SIGMA."""
    bins, counts = histogram.total(hists)
    return max(NMAD_SCALE * histogram.median(bins * DEVIATION_STEP, counts), MIN_SIGMA) if counts.sum() else MIN_SIGMA


@register
class RegionGrowing(MatchingStrategy):
    """Region-growing least-squares matching (Otto & Chau 1989; Heipke et al. 1992; Kornus et al. 2006)."""

    name = "region_growing"
    settings_type = RegionGrowingSettings
    spacing_setting = "grow.step"
    second_round = "the consistency test and MPGC"
    first_share = 75.0

    @classmethod
    def plan(cls, stereo: StereoSet, settings: RegionGrowingSettings, feedback: Feedback | None) -> TilePlan:
        use_tie_points, automatic = SEED_SOURCES[settings.seeds]
        seed_points = stereo.tie_points() if use_tie_points and stereo.tie_points is not None else None
        if seed_points is None and not automatic:
            raise InputError("region growing needs seeds: give seed points or allow automatic seeds")
        log, s, params = progress.ensure(feedback), stereo, settings.grow

        def seeds(k: int) -> np.ndarray | None:
            if seed_points is None:
                return None
            found = pair_seeds(s, k, seed_points, params)
            log.pushInfo(f"{s.names[0]} - {s.names[k]}: {len(found)} seeds from the given points")
            return found

        grow_a, tiles = grow_job(
            ImagePair(s.images[0], s.images[1], s.models[0], s.models[1]), params, s.heights.bounds, seeds(1), automatic
        )
        grow_b = None
        if s.triplet and settings.grow_second:
            grow_b = grow_job(
                ImagePair(s.images[0], s.images[2], s.models[0], s.models[2]),
                params,
                s.heights.bounds,
                seeds(2),
                automatic,
            )[0]
        n = s.names
        log.pushInfo(
            f"{len(tiles)} tile(s) of {params.tile} px: "
            + (
                f"(a) {n[0]} - {n[1]}, (b) {n[0]} - {n[2]}, (c) {n[2]} - {n[1]}"
                if s.triplet
                else f"(a) {n[0]} - {n[1]}"
            )
        )
        job = TileJob(s.without_loader(), settings, grow_a, grow_b, settings.mpgc and s.triplet)
        return TilePlan(job, tiles, sample_quotas([(n_b - n_a) * (m_b - m_a) for n_a, n_b, m_a, m_b in tiles]))

    @staticmethod
    def match_tile(job: TileJob, index: int, box: Any, out: str, quota: int) -> dict[str, Any]:
        """Round 1 (module docstring): the tile combined without the consistency test."""
        ids = job.stereo.ids
        a, tries, seeds = _grow_tile(job.grow_a, index, box)
        check_cancel()  # between the combinations (execution: a cancel reaches a running tile)
        if not job.stereo.triplet:
            multi = combine(a, image_ids=ids)
            dx = dy = np.full(len(multi), np.nan)
        else:
            grown = _grow_tile(job.grow_b, index, box)[0] if job.grow_b is not None else None
            check_cancel()
            bt, ok = _transfer(job, (0, 2), a["x1"], a["y1"], grown)
            b, b_src = bt[ok], np.flatnonzero(ok)
            b["x1"], b["y1"] = a["x1"][b_src], a["y1"][b_src]  # transfer points keep image 0 exactly
            if grown is not None:
                fresh = grown[new_cells(grown["x1"], grown["y1"], a["x1"], a["y1"], job.settings.grow.step)]
                b = np.concatenate([b, fresh])
                b_src = np.concatenate([b_src, np.full(len(fresh), -1)])
            check_cancel()
            ct, ok = _transfer(job, (2, 1), b["x2"], b["y2"], compose_guide(a, b, b_src))
            c, c_src = ct[ok], np.flatnonzero(ok)
            c["x1"], c["y1"] = b["x2"][c_src], b["y2"][c_src]
            multi, dx, dy = combine(
                a, Transfer(b, b_src), Transfer(c, c_src), image_ids=ids, sigma_factor=np.inf, deviations=True
            )
        save_work(out, multi)
        save_array(out + ".deviations.npy", np.column_stack([dx, dy]), "the matched tiles")
        both = np.flatnonzero(np.isfinite(dx))
        take = evenly(both, quota)
        cols, rows = positions(multi, ids, take)
        return {
            "points": len(multi),
            **{k: histogram.count(np.round(np.abs(d[both]) / DEVIATION_STEP)) for k, d in (("dx", dx), ("dy", dy))},
            "sample": (cols, rows, dx[take], dy[take]),
            "tries": tries,
            "seeds": seeds,
            **{k: multi.stats.get(k, 0) for k in ADDED},
        }

    @classmethod
    def between(
        cls, job: TileJob, first: list[dict[str, Any]], outs: list[str], rounds: Rounds, feedback: Feedback | None
    ) -> tuple[TileJob, list[int]]:
        """The consistency test's limits, each tile's points that pass, and the scene's MPGC orientation."""
        sigmas = (_robust_sigma(t["dx"] for t in first), _robust_sigma(t["dy"] for t in first))
        factor = job.settings.sigma_factor
        limits = (factor * sigmas[0], factor * sigmas[1])
        counts = rounds(_kept, [(out, limits) for out in outs], "the consistency test's counts")
        bias = None
        if job.mpgc:
            cols, rows, dx, dy = (np.concatenate([t["sample"][i] for t in first], axis=-1) for i in range(4))
            keep = (np.abs(dx) < limits[0]) & (np.abs(dy) < limits[1])
            bias = scene_bias(job.stereo.models, cols[:, keep], rows[:, keep])
        return job._replace(limits=limits, sigmas=sigmas, bias=bias), counts

    @staticmethod
    def keep(job: TileJob, out: str) -> np.ndarray | None:
        return _passes(*np.load(out + ".deviations.npy").T, job.limits)

    @staticmethod
    def refine(job: TileJob, points: MultiPoints) -> dict[str, Any]:
        if not job.mpgc or job.bias is None:
            return {}
        check_cancel()
        s = job.stereo
        refine_three_ray(points, s, job.settings.grow, bias=job.bias)
        return points.stats

    @classmethod
    def stats(cls, job: TileJob, rounds: RoundResults, feedback: Feedback | None) -> MatchStats:
        first, refined, counts = rounds
        s = job.stereo
        added = {k: int(sum(t[k] for t in first)) for k in ADDED}
        candidates = int(sum(t["dx"][1].sum() for t in first))
        details: dict[str, Any] = {k: v for k, v in added.items() if k != "matched_3"}
        details["rejected_3sigma"] = int(sum(t["points"] for t in first) - sum(counts))
        stats = MatchStats(
            cls.name,
            list(s.ids if s.triplet else s.ids[:2]),
            int(sum(counts)),
            matched_3=added["matched_3"],
            sigma_factor=float(job.settings.sigma_factor),
            sigma_dx=job.sigmas[0] if candidates else None,
            sigma_dy=job.sigmas[1] if candidates else None,
            details=details,
        )
        if job.bias is not None:
            done = [r for r in refined if "refined_mpgc" in r]
            stats.refined_mpgc = int(sum(r["refined_mpgc"] for r in done))
            if done:  # the scene's orientation: the same in every tile
                details.update({k: done[0][k] for k in ("refine_sigma_geometry_px", "refine_bias_px")})
        tries, nseeds = sum(t["tries"] for t in first), sum(t["seeds"] for t in first)
        if added["matched_a"] == 0:
            progress.warn(
                feedback,
                "region growing found no matched point: no seed passed the acceptance criteria "
                f"({nseeds} seed(s) in {len(first)} tile(s)); check the image pair, the height "
                "range and the texture, or give seeds",
            )
        progress.ensure(feedback).pushInfo(
            f"region growing (a): {added['matched_a']} points of {tries} LSM attempts from {nseeds} seed(s); "
            f"{stats.points} points kept"
            + (f", {details['rejected_3sigma']} failed the consistency test" if s.triplet else "")
        )
        return stats


def match_block(
    images: Sequence[Any],
    models: Sequence[Any],
    params: GrowParams | None = None,
    height_range: GivenHeights = None,
    workers: int | Execution = 1,
    names: Sequence[str] | None = None,
    mpgc: bool = True,
    feedback: Feedback | None = None,
) -> MultiPoints:
    """Region growing of 2 or 3 images in combination order (reference/nadir, forward, backward; block ids 1, 2,
    3) with automatic seeds and the GrowParams `params`, MPGC refinement of the group 3 points where `mpgc`, on
    `workers` threads (or an execution.Execution whose workers see this machine's temporary folder), gathered in
    memory (tiled_rounds.match_in_memory): for scenes that fit, studies and tests."""
    execution = workers if isinstance(workers, Execution) else Execution("threads", max(int(workers), 1))
    return match_in_memory(
        RegionGrowing,
        StereoSet.of(images, models, names, heights=height_range),
        RegionGrowingSettings(grow=params or GrowParams(), mpgc=mpgc),
        execution,
        feedback,
    )
