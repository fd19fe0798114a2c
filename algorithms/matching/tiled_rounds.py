"""The one driver of every matching strategy (strategy.py): a stereo set matched tile by tile in two rounds on
the chosen execution (execution.run_tasks), so that memory follows the tile and the number of workers, not the
scene.

Round 1 runs the strategy's `match_tile` per tile; each writes its points to a work file (two .npy arrays) in a
work folder beside the output folder (atomic.work_dir), where every worker sees them. `between` runs in the
step's process on what the tiles returned. Round 2 numbers each tile's kept points on from the tiles before it
(ids 1 ... N in tile order), lets the strategy refine them, and hands them to `write_part(folder, k, points)`
(the step passes block/points.write_part, which writes them as the k-th part of the new point folder), or
returns them. The rounds share one session of workers. The result does not depend on the execution or the
number of workers: a tile's points depend only on its box and on what `between` derives from all tiles.

The scene-wide orientation bias that MPGC refines with (region growing, dense matching) is fitted to a sample of
the tiles' points: BIAS_SAMPLE points over the scene, each tile's quota in proportion to its area
(sample_quotas), as the scene matched at once would be fitted to all its points (orientation_bias.affine_bias;
refinement.MIN_POINTS at least)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from typing import Any, Callable

import numpy as np

from .. import progress
from ..atomic import save_array, work_dir
from ..execution import Execution, run_tasks, session
from ..progress import Feedback
from .match_stats import MatchStats
from .orientation_bias import affine_bias
from .points import MultiPoints
from .refinement import MIN_POINTS
from .stereo_set import StereoSet
from .strategy import MatchingStrategy, RoundResults

#: points of the scene that the orientation bias is fitted to
BIAS_SAMPLE = 50_000
#: writes a tile's points as the k-th part of the folder: write_part(folder, k, points) -> its index entry
WritePart = Callable[[str, int, MultiPoints], Any]


def save_work(out: str, points: MultiPoints) -> None:
    """Write a tile's points to the work file `out` (round 1)."""
    save_array(out + ".points.npy", points.points, "the matched tiles")
    save_array(out + ".observations.npy", points.observations, "the matched tiles")


def load_work(out: str) -> MultiPoints:
    """The points of the work file `out`."""
    return MultiPoints(np.load(out + ".points.npy"), np.load(out + ".observations.npy"))


def renumber(points: MultiPoints, keep: np.ndarray | None, first_id: int) -> MultiPoints:
    """The points `keep` selects (None: all) with their observations, numbered first_id, first_id + 1, ... in
    their order."""
    p = points.points
    kept = p if keep is None else p[keep]
    obs = points.observations
    obs = obs if keep is None else obs[np.isin(obs["point_id"], kept["id"])]
    new_id = np.zeros(int(p["id"].max(initial=0)) + 1, np.int64)
    new_id[kept["id"]] = first_id + np.arange(len(kept))
    kept["id"], obs["point_id"] = new_id[kept["id"]], new_id[obs["point_id"]]
    return MultiPoints(kept, obs, {})


def first_ids(counts: Sequence[int]) -> list[int]:
    """The first point id of each tile whose points number `counts`, so that ids run 1 ... N in tile order."""
    return [int(i) for i in np.concatenate([[1], 1 + np.cumsum(counts)[:-1]])] if len(counts) else []


def sample_quotas(areas: Sequence[float]) -> list[int]:
    """Each tile's share of BIAS_SAMPLE, in proportion to its area (`areas`, any unit)."""
    area = np.asarray(areas, float)
    return [int(q) for q in np.ceil(BIAS_SAMPLE * area / max(area.sum(), 1.0)).astype(int)]


def evenly(candidates: np.ndarray, quota: int) -> np.ndarray:
    """Up to `quota` of the indices `candidates`, spread evenly over them."""
    if not len(candidates):
        return candidates
    return candidates[np.unique(np.linspace(0, len(candidates) - 1, min(len(candidates), quota)).astype(int))]


def positions(points: MultiPoints, ids: Sequence[int], which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(cols, rows), each images x points: the image positions of the points `which` in the images `ids`."""
    cols, rows = (np.array(v)[:, which] for v in zip(*(points.coordinates(i) for i in ids)))
    return cols, rows


def scene_bias(models: Sequence[Any], cols: np.ndarray, rows: np.ndarray) -> tuple[Any, float] | None:
    """(corrected models, systematic px) of orientation_bias.affine_bias fitted to the sampled positions `cols`,
    `rows` (images x points); None for fewer than refinement.MIN_POINTS points."""
    if cols.shape[-1] < MIN_POINTS:
        return None
    corrected, _, systematic = affine_bias(list(models), cols, rows)
    return corrected, systematic


def _first(strategy: type[MatchingStrategy], job: Any, index: int, box: Any, out: str, quota: int) -> dict:
    return strategy.match_tile(job, index, box, out, quota)


def _second(
    strategy: type[MatchingStrategy],
    job: Any,
    out: str,
    first_id: int,
    k: int,
    folder: str,
    write_part: WritePart | None,
) -> tuple[Any, dict]:
    points = renumber(load_work(out), strategy.keep(job, out), first_id)
    refined = strategy.refine(job, points)
    return (points if write_part is None else write_part(folder, k, points)), refined


def match_in_tiles(
    strategy: type[MatchingStrategy],
    stereo: StereoSet,
    settings: Any,
    folder: str,
    write_part: WritePart | None = None,
    execution: Execution | None = None,
    feedback: Feedback | None = None,
) -> tuple[list[Any], MatchStats]:
    """Match `stereo` with `strategy` and its `settings` tile by tile (module docstring): each tile's points handed
    to `write_part(folder, k, points)` (a module-level function: block/points.write_part), or, without it,
    returned. Returns (the index entries or MultiPoints of the tiles, in id order; the run's MatchStats). The
    work folder lies beside `folder`. Raises InputError (the strategy's, for its settings and inputs),
    CancelledError when cancelled, ExecutionError where the workers fail."""
    settings = strategy.settings(settings)
    execution = execution or Execution("threads", 1)
    plan = strategy.plan(stereo, settings, feedback)
    share = strategy.first_share
    with work_dir(folder, "the matched tiles") as work, session(execution):  # the rounds share workers
        pre = [os.path.join(work, f"tile-{k:05d}") for k in range(len(plan.boxes))]
        first = run_tasks(
            _first,
            [
                (strategy, plan.job, k, box, out, int(q))
                for k, (box, out, q) in enumerate(zip(plan.boxes, pre, plan.quotas))
            ],
            execution,
            progress.scaled(feedback, 0, share),
            strategy.first_round,
        )

        def rounds(function: Callable[..., Any], arguments: Sequence[tuple], what: str) -> list[Any]:
            return run_tasks(function, list(arguments), execution, progress.scaled(feedback, share, share), what)

        job, counts = strategy.between(plan.job, first, pre, rounds, feedback)
        second = run_tasks(
            _second,
            [
                (strategy, job, out, first_id, k, folder, write_part)
                for k, (out, first_id) in enumerate(zip(pre, first_ids(counts)))
            ],
            execution,
            progress.scaled(feedback, share, 100),
            strategy.second_round,
        )
    stats = strategy.stats(job, RoundResults(first, [s for _, s in second], counts), feedback)
    return [part for part, _ in second], stats


def gather(parts: Sequence[MultiPoints], stats: MatchStats) -> MultiPoints:
    """One MultiPoints of the tiles' parts (in id order), with the run's stats as a dict."""
    if not parts:
        return MultiPoints(stats=stats.as_dict())
    return MultiPoints(
        np.concatenate([p.points for p in parts]), np.concatenate([p.observations for p in parts]), stats.as_dict()
    )


def match_in_memory(
    strategy: type[MatchingStrategy],
    stereo: StereoSet,
    settings: Any = None,
    execution: Execution | None = None,
    feedback: Feedback | None = None,
) -> MultiPoints:
    """match_in_tiles with the points gathered in memory (the work folder in this machine's temporary folder): for
    scenes that fit, studies and tests. A whole scene goes through the matching step, which writes part by part."""
    parts, stats = match_in_tiles(
        strategy,
        stereo,
        settings,
        os.path.join(tempfile.gettempdir(), f"pushbroom-{strategy.name}"),
        None,
        execution,
        feedback,
    )
    return gather(parts, stats)
