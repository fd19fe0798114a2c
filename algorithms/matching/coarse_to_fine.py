"""Coarse-to-fine multi-primitive matching with MPGC, the second dense-matching strategy (Zhang &
Gruen): the orchestration. The work of one pyramid level is in coarse_to_fine_level.py.

0. Tiles: a reference image larger than `tile` px is cut into tiles (tiling.tile_grid), each a task
   of the two rounds of tiled_rounds.py on the chosen execution, matched with TILE_MARGIN px of context
   in windows of the adapted images (the search windows: pair_geometry.search_box), each keeping the
   points of its core; the orientation bias is estimated per tile. Memory is bounded by the tile size
   (MAX_PIXELS) and the number of workers.
1. Preprocessing (preprocess.py): the reference (nadir) is low-passed to the search images'
   footprint (resolution.adapt_resolution), every image Wallis-filtered and reduced to a
   factor-3 pyramid; the number of levels brings the parallax range of the block's height range
   to about `search_px_at_top` px at the top level (preprocess.levels_for), as far as the top
   level keeps 3 of the largest windows across the smallest image.
2. From the top level down, each level's points (coarse_to_fine_level.match_level, and with
   `edge_points` match_level_edges) over the height interval its predecessor's TIN gives; the
   search images' orientation bias estimated per level is compensated from then on (ShiftedModel).
3. A TIN of each level's accepted points (coarse_to_fine_level.TinGuide, with the matched edge
   chains as breaklines when `breaklines`) guides the next level.
4. Level 0's points go through MPGC (mpgc.match_points) in all their images at once. Points MPGC
   does not accept but that converged within the shift limit keep MPGC's positions with its
   lowered reliability (mpgc.py: rho x ellipse and geometric-test ratios); the others keep their
   NCC positions with the low reliability NCC_RELIABILITY x rho; both are flagged NCC_ONLY.
5. Output: MultiPoints (points.py) with group 3 (reference + 2 search images) or 1 (reference + 1),
   rho_min = the reliability (MPGC's, or the NCC one), flags COMB_A / COMB_B for the search images
   1 / 2 observed (+ NCC_ONLY, EDGE), stats with provenance "coarse_to_fine" and the timings per
   level.

Failure modes: InputError for other than 2 or 3 images, or where no tile gives points (a level with
fewer than 3 points, a search window over MAX_PIXELS, no tile inside the search images: the first
reason is given); CancelledError when cancelled. Why `edge_points` is
off by default: docs/validation.md."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from .. import progress
from ..errors import InputError
from ..execution import Execution
from ..height_range import GivenHeights
from ..progress import Feedback
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from . import preprocess
from .coarse_to_fine_level import (
    FACTOR,
    LevelImages,
    ShiftedModel,
    TinGuide,
    edge_breaklines,
    match_level,
    match_level_edges,
)
from .edges import canny, link
from .imagery import Window
from .match_stats import MatchStats
from .mpgc import MpgcParams, accepted, match_points
from .pair_geometry import predict, search_box
from .points import COMB_A, COMB_B, EDGE, NCC_ONLY, OBS_DTYPE, POINT_DTYPE, MultiPoints
from .resolution import adapted_images
from .stereo_set import StereoSet
from .strategy import MatchingStrategy, RoundResults, Rounds, TilePlan, register
from .tiled_rounds import match_in_memory, save_work

#: reliability of a point that failed MPGC: this factor x its smallest NCC rho
NCC_RELIABILITY = 0.25


#: the largest window (pixels) matched in one piece, the search windows of a tile included: each is held
#: whole with its pyramids, candidates and level TINs (memory per pixel: docs/validation.md)
MAX_PIXELS = 40_000_000
#: px of the reference image around a tile's core matched with it (context for the windows, the
#: relaxation and the TINs; its points are dropped) and added around the search windows
TILE_MARGIN = 256


@dataclass
class CoarseToFineParams:
    """Parameters of the coarse-to-fine matcher (module docstring)."""

    search_px_at_top: float = 4.0  # parallax range (px) at the top level
    grid: int = 10  # px between grid points at level 0
    coarse_grid: int = 6  # px between grid points above level 0
    patch: int = 16  # px: one Foerstner point per patch x patch cell (every level)
    windows: tuple = (9, 15, 21)  # candidate window sizes (px, every level)
    precision: float = 0.05  # px: window choice target (coarse_to_fine_level.window_halves)
    rho_min: float = 0.7  # NCC threshold at level 0
    rho_min_coarse: float = 0.6  # NCC threshold above level 0
    rho_drop: float = 0.1  # NCC threshold lowered by up to this where the TIN is rough (1 px parallax)
    max_candidates: int = 5
    peak_ratio: float = 0.9  # second / first peak below this: unique
    margin: float = 0.05  # score margin of the best hypothesis: unique
    agree_px: float = 1.0  # px of parallax: two images' heights agree
    tol_px: float = 3.0  # px of parallax around the TIN height below the top level
    across: float = 3.0  # px (full resolution) searched across the path
    top_margin_px: float = 2.0  # px of parallax added to the height range at the top level
    back_px: float = 1.0  # px (level): back-matching tolerance
    relax_radius: float = 3.0  # in grid spacings
    blunder_k: float = 4.0  # TIN blunder filter, robust sigmas
    wallis: bool = True
    tile: int = 4096  # px: square tiles of the reference image (cores; memory: MAX_PIXELS)
    edges: bool = True  # relaxation does not cross the reference level's Canny edges (step 2)
    edge_points: bool = False  # edge chains matched with figural continuity become points (off: blunders
    #                                    on steep forest, docs/validation.md)
    breaklines: bool = True  # matched edge chains are breaklines of the level TIN (step 3)
    edge_window: int = 7  # px: NCC window of edge matching (every level)
    edge_step: int = 2  # every edge_step-th edgel of a chain is matched
    edge_min_length: int = 10  # px: shorter edge chains are dropped
    edge_min_level: int = 1  # edge points on this pyramid level and above (coarse_to_fine_level)
    final: MpgcParams = field(default_factory=lambda: MpgcParams(sigma_geometry=0.5))  # MPGC

    def check(self):
        if self.grid < 2 or self.coarse_grid < 2 or self.patch < 3:
            raise InputError("grid spacings must be >= 2 px and the Foerstner patch >= 3 px")
        if not self.windows or any(int(w) < 5 or int(w) % 2 == 0 for w in self.windows):
            raise InputError(f"window sizes must be odd and >= 5 px, got {self.windows}")
        lowest = min(self.rho_min, self.rho_min_coarse)
        if not (0 < self.rho_min < 1 and 0 < self.rho_min_coarse < 1 and 0 <= self.rho_drop < lowest):
            raise InputError("rho thresholds must lie between 0 and 1, and rho_drop between 0 and the thresholds")
        if (
            self.edge_window < 3
            or self.edge_window % 2 == 0
            or self.edge_step < 1
            or self.edge_min_length < 2
            or self.edge_min_level < 0
        ):
            raise InputError(
                "the edge window must be odd and >= 3 px, the edgel step >= 1, the chain length >= 2 "
                "and the edge level >= 0"
            )
        if self.tile < 2 * TILE_MARGIN:
            raise InputError(f"tiles must be at least {2 * TILE_MARGIN} px, got {self.tile}")
        if self.max_candidates < 1 or self.search_px_at_top <= 0 or self.tol_px <= 0 or self.agree_px <= 0:
            raise InputError("max_candidates, search_px_at_top, tol_px and agree_px must be positive")
        self.final.check()
        return self


def _pyramids(adapted, models, hr, params):
    """Per image (NCC pyramid, raw pyramid) of the adapted images; levels; parallax range (px)."""
    cols, rows = models[0].size
    cx, cy = np.array([0.5 * cols]), np.array([0.5 * rows])
    parallax = max(
        float(
            np.hypot(
                *(
                    np.subtract(
                        predict(models[0], mk, cx, cy, np.array([hr[1]])),
                        predict(models[0], mk, cx, cy, np.array([hr[0]])),
                    )
                )
            )
        )
        for mk in models[1:]
    )
    levels = preprocess.levels_for(parallax if math.isfinite(parallax) else 0.0, params.search_px_at_top, FACTOR)
    # the top level keeps at least 3 of the largest windows across the smallest image
    smallest = min(min(m.size) for m in models)
    levels = max(1, min(levels, int(math.floor(math.log(max(smallest / (3 * max(params.windows)), 1.0), FACTOR))) + 1))
    largest = max(int(np.prod(image.size)) for image in adapted)
    if largest > MAX_PIXELS:
        raise InputError(
            f"a search window of the coarse-to-fine strategy would be {largest / 1e6:.0f} Mpx (at most "
            f"{MAX_PIXELS / 1e6:.0f} Mpx are held at once): narrow the terrain height range or make the "
            "tiles smaller"
        )
    pyr = []
    for image in adapted:
        raw = image.read(0, 0, *image.size)[0]
        ncc = preprocess.wallis(raw) if params.wallis else raw
        pyr.append((preprocess.pyramid(ncc, levels, FACTOR), preprocess.pyramid(raw, levels, FACTOR)))
    return pyr, levels, parallax


def _tile_windows(adapted, models, core, hr, grid):
    """Windows (imagery.Window) and window models (ShiftedModel) of one tile: the reference core
    plus TILE_MARGIN (its corner on a multiple of `grid`, so level 0's grid points are the whole
    image's), and per search image pair_geometry.search_box of it with TILE_MARGIN, clipped to the
    images; None where a search window is empty."""

    def clip(box, size):
        x0, y0 = max(int(math.floor(box[0])), 0), max(int(math.floor(box[1])), 0)
        x1, y1 = min(int(math.ceil(box[2])), size[0]), min(int(math.ceil(box[3])), size[1])
        return (x0, y0, x1, y1) if min(x1 - x0, y1 - y0) >= TILE_MARGIN // 2 else None

    ref = clip(
        (
            max(core[0] - TILE_MARGIN, 0) // grid * grid,
            max(core[1] - TILE_MARGIN, 0) // grid * grid,
            core[2] + TILE_MARGIN,
            core[3] + TILE_MARGIN,
        ),
        models[0].size,
    )
    boxes = [ref]
    for mk in models[1:]:
        box = search_box(models[0], mk, ref, hr, TILE_MARGIN)
        box = None if box is None else clip(box, mk.size)
        if box is None:
            return None
        boxes.append(box)
    windows = [Window(image, b[0], b[1], b[2] - b[0], b[3] - b[1]) for image, b in zip(adapted, boxes)]
    wmodels = [ShiftedModel(mk, -b[0], -b[1], (b[2] - b[0], b[3] - b[1])) for mk, b in zip(models, boxes)]
    return windows, wmodels, boxes


def _match(adapted, models, params, hr, feedback):
    """The coarse-to-fine matching of one piece (the images or the windows of a tile): (the final
    points `_final`, statistics)."""
    log = progress.ensure(feedback)
    n = len(adapted)
    t0 = time.perf_counter()
    pyr, levels, parallax = _pyramids(adapted, models, hr, params)
    timings = {"preprocessing": time.perf_counter() - t0}
    log.pushInfo(f"{levels} pyramid levels (factor {FACTOR}) for a parallax range of {parallax:.1f} px")
    guide, result = None, None
    counts, edge_counts = {}, {}
    shifts = np.zeros((n - 1, 2))
    for level in range(levels - 1, -1, -1):
        t = time.perf_counter()
        progress.step(feedback, 80.0 * (levels - 1 - level) / levels)
        current = [models[0]] + [ShiftedModel(mk, *d) for mk, d in zip(models[1:], shifts)]
        ref, searches = pyr[0][0][level], [p[0][level] for p in pyr[1:]]
        mask, chains = None, []
        if params.edges or params.edge_points:
            mask = canny(pyr[0][1][level])
            chains = link(mask, params.edge_min_length)
        result = match_level(
            LevelImages(ref, pyr[0][1][level], searches),
            current,
            level,
            params,
            hr,
            guide,
            edge_mask=mask if params.edges else None,
        )
        shifts = shifts + result["shifts"]
        s = float(FACTOR) ** level
        if len(result["x"]) < 3:
            raise InputError(
                f"level {level}: only {len(result['x'])} points matched; check the images, the models "
                "and the height range"
            )
        result["edge"] = np.zeros(len(result["x"]), bool)
        lines = []
        if params.edge_points and chains and level >= params.edge_min_level:
            edge = match_level_edges(
                ref,
                searches,
                [models[0]] + [ShiftedModel(mk, *d) for mk, d in zip(models[1:], shifts)],
                level,
                params,
                hr,
                guide,
                chains,
            )
            edge_counts[f"level {level}"] = {
                "chains": len(chains),
                "edgels": edge["edgels"],
                "matched": int(len(edge["x"])),
            }
            if params.breaklines:
                lines = edge_breaklines(edge, s, params.edge_step)
            edge["edge"] = np.ones(len(edge["x"]), bool)
            for key in ("x", "y", "h", "sx", "sy", "rho", "edge"):
                result[key] = np.concatenate([result[key], edge[key]])
        timings[f"level {level}"] = time.perf_counter() - t
        counts[f"level {level}"] = int(len(result["x"]))
        if level > 0:  # the TIN guides the next level
            mass = ~result["edge"] if lines else np.ones(len(result["x"]), bool)
            guide = TinGuide(
                result["x"][mass] * s,
                result["y"][mass] * s,
                result["h"][mass],
                pyr[0][0][0].shape,
                max(s / FACTOR, 1.0),
                params.blunder_k,
                lines,
                spacing=s,
            )
        log.pushInfo(
            f"level {level}: {len(result['x'])} points ({int(result['edge'].sum())} on edges) "
            f"in {timings[f'level {level}']:.2f} s"
        )
    progress.step(feedback, 80.0, f"MPGC of {len(result['x'])} points")
    t = time.perf_counter()
    log.pushInfo(
        "orientation bias of the search images (px): " + ", ".join(f"({d[0]:.2f}, {d[1]:.2f})" for d in shifts)
    )
    out = _final(adapted, [models[0]] + [ShiftedModel(mk, *d) for mk, d in zip(models[1:], shifts)], result, params)
    timings["mpgc"] = time.perf_counter() - t
    stats = {
        "provenance": "coarse_to_fine",
        "levels": levels,
        "points_per_level": counts,
        "seconds": {k: round(v, 3) for k, v in timings.items()},
        "mpgc_failed": int(np.count_nonzero(~out["mpgc_ok"])),
        "edges_per_level": edge_counts,
        "edge_points": int(np.count_nonzero(out["edge"])),
        "edge_points_mpgc": int(np.count_nonzero(out["edge"] & out["mpgc_ok"])),
        "search_image_shifts_px": shifts.round(3).tolist(),
    }
    return out, stats


def _final(adapted, models, result, params):
    """MPGC of level 0's points in the images each was matched in (module docstring, step 4)."""
    x0, y0, h = result["x"], result["y"], result["h"]
    m = result["sx"].shape[1]
    lon, lat = models[0].image_to_ground(x0, y0, h)
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    sx, sy, rho = result["sx"].copy(), result["sy"].copy(), result["rho"].copy()
    ok = np.zeros(len(x0), bool)
    rel = np.full(len(x0), np.nan)
    ellipse = np.zeros((len(x0), m, 2))
    present = np.isfinite(sx)
    for combo in {tuple(np.flatnonzero(p)) for p in present}:
        idx = np.flatnonzero((present == np.isin(np.arange(m), combo)).all(axis=1))
        rec = match_points(
            adapted[0],
            [adapted[k + 1] for k in combo],
            [models[0]] + [models[k + 1] for k in combo],
            x0[idx],
            y0[idx],
            (lon[idx], lat[idx], h[idx]),
            params.final,
        )
        good = accepted(rec, params.final)
        placed = rec["reliability"] > 0  # converged within the shift: MPGC's position, even if not accepted
        g = idx[placed]
        for c, k in enumerate(combo):
            sx[g, k], sy[g, k], rho[g, k] = rec["x"][placed, c], rec["y"][placed, c], rec["rho"][placed, c]
            ellipse[g, k] = np.column_stack([rec["semi_major"][placed, c], rec["semi_minor"][placed, c]])
        ok[idx[good]] = True
        rel[g] = rec["reliability"][placed]
    ncc = np.isnan(rel)
    rel[ncc] = NCC_RELIABILITY * np.nanmin(np.where(present, rho, np.nan), axis=1)[ncc]
    return {
        "x0": x0,
        "y0": y0,
        "sx": sx,
        "sy": sy,
        "rho": rho,
        "ellipse": ellipse,
        "reliability": rel,
        "mpgc_ok": ok,
        "edge": result.get("edge", np.zeros(len(x0), bool)),
    }


def to_multipoints(out, image_ids, stats):
    """MultiPoints of the final points (module docstring, step 5)."""
    n, m = out["sx"].shape
    present = np.isfinite(out["sx"])
    points = np.zeros(n, POINT_DTYPE)
    points["id"] = np.arange(1, n + 1)
    points["group"] = np.where(present.sum(axis=1) == 2, 3, 1)
    points["flags"] = (
        present[:, 0] * COMB_A
        + (present[:, 1] * COMB_B if m > 1 else 0)
        + (~out["mpgc_ok"]) * NCC_ONLY
        + out["edge"] * EDGE
    ).astype(np.uint8)
    points["rho_min"] = out["reliability"]
    points["rho_a"] = out["rho"][:, 0]
    points["rho_b"] = out["rho"][:, 1] if m > 1 else np.nan
    points["rho_c"] = points["dx"] = points["dy"] = np.nan
    blocks = []
    obs = np.zeros(n, OBS_DTYPE)
    obs["point_id"], obs["image_id"] = points["id"], image_ids[0]
    obs["col"], obs["row"], obs["rho"] = out["x0"], out["y0"], np.nan
    blocks.append(obs)
    for k in range(m):
        obs = np.zeros(n, OBS_DTYPE)
        obs["point_id"], obs["image_id"] = points["id"], image_ids[k + 1]
        obs["col"], obs["row"], obs["rho"] = out["sx"][:, k], out["sy"][:, k], out["rho"][:, k]
        obs["semi_major"], obs["semi_minor"] = out["ellipse"][:, k, 0], out["ellipse"][:, k, 1]
        blocks.append(obs[present[:, k]])
    observations = np.concatenate(blocks)
    observations = observations[np.lexsort((observations["image_id"], observations["point_id"]))]
    stats = {
        **stats,
        "images": [int(i) for i in image_ids],
        "group3": int(np.count_nonzero(points["group"] == 3)),
        "group1": int(np.count_nonzero(points["group"] == 1)),
    }
    return MultiPoints(points, observations, stats)


class TileJob(NamedTuple):
    """What every tile shares: the resolution-adapted images, the set (models, ids), the settings and the
    height range (h_min, h_max) searched; `whole`: one tile, matched in the whole images."""

    adapted: list[Any]
    stereo: StereoSet
    params: CoarseToFineParams
    hr: tuple[float, float]
    whole: bool


@register
class CoarseToFine(MatchingStrategy):
    """Zhang & Gruen's coarse-to-fine multi-primitive matching with MPGC (module docstring)."""

    name = "coarse_to_fine"
    settings_type = CoarseToFineParams
    spacing_setting = "grid"
    first_round = "coarse-to-fine matching"

    @classmethod
    def plan(cls, stereo: StereoSet, settings: CoarseToFineParams, feedback: Feedback | None) -> TilePlan:
        s = stereo.without_loader()
        progress.step(feedback, 0, "coarse-to-fine matching: preprocessing (resolution adaptation, Wallis, pyramids)")
        adapted = adapted_images(list(s.images), list(s.models), s.heights.bounds)
        boxes = tile_grid(s.models[0].size, settings.tile)
        job = TileJob(adapted, s, settings, s.heights.bounds, len(boxes) == 1)
        return TilePlan(job, boxes, [0] * len(boxes))

    @staticmethod
    def match_tile(job: TileJob, index: int, box: Any, out: str, quota: int) -> dict[str, Any]:
        """Round 1: the tile's points (those of its core) to the work file `out`; its stats, or why it has
        none."""
        core = [int(v) for v in box]
        check_cancel()
        if job.whole:
            windows, wmodels, boxes = job.adapted, list(job.stereo.models), None
        else:
            tile = _tile_windows(job.adapted, list(job.stereo.models), box, job.hr, int(job.params.grid))
            if tile is None:
                save_work(out, MultiPoints())
                return {"points": 0, "core": core, "failure": None}
            windows, wmodels, boxes = tile
        try:
            found, stats = _match(windows, wmodels, job.params, job.hr, None)
        except InputError as exc:
            save_work(out, MultiPoints())
            return {"points": 0, "core": core, "failure": str(exc)}
        if boxes is not None:
            found["x0"] += boxes[0][0]
            found["y0"] += boxes[0][1]
            for j, b in enumerate(boxes[1:]):
                found["sx"][:, j] += b[0]
                found["sy"][:, j] += b[1]
            mine = (found["x0"] >= box[0]) & (found["x0"] < box[2]) & (found["y0"] >= box[1]) & (found["y0"] < box[3])
            found = {key: v[mine] for key, v in found.items()}
        points = to_multipoints(found, job.stereo.ids, {})
        save_work(out, points)
        return {
            **stats,
            "points": len(points),
            "core": core,
            "failure": None,
            "mpgc_failed": int((~found["mpgc_ok"]).sum()),
            "edge_points": int(found["edge"].sum()),
            "edge_points_mpgc": int((found["edge"] & found["mpgc_ok"]).sum()),
            **{f"group{g}": int((points.points["group"] == g).sum()) for g in (1, 3)},
        }

    @classmethod
    def between(
        cls, job: TileJob, first: list[dict[str, Any]], outs: list[str], rounds: Rounds, feedback: Feedback | None
    ) -> tuple[TileJob, list[int]]:
        """Each tile's outcome in the log; InputError where no tile gave points."""
        log = progress.ensure(feedback)
        for k, t in enumerate(first):
            if t["points"] == 0 and not job.whole:
                log.pushInfo(
                    f"tile {k + 1} {tuple(t['core'])}: "
                    + (f"no points ({t['failure']})" if t["failure"] else "outside the search images, skipped")
                )
            elif t["points"]:
                log.pushInfo(
                    f"tile {k + 1} {tuple(t['core'])}: {t['points']} points, {t['levels']} pyramid levels, "
                    "points per level " + ", ".join(f"{v}" for v in t["points_per_level"].values())
                )
        if not any(t["points"] for t in first):
            failures = [t["failure"] for t in first if t["failure"]]
            raise InputError(
                "no tile of the reference image gave points"
                + (f" ({failures[0]})" if failures else " (none lies inside the search images)")
            )
        return job, [int(t["points"]) for t in first]

    @classmethod
    def stats(cls, job: TileJob, rounds: RoundResults, feedback: Feedback | None) -> MatchStats:
        first, refined, counts = rounds
        s = job.stereo
        matched = [t for t in first if t["points"]]
        seconds: dict[str, float] = {}
        per_level: dict[str, int] = {}
        for t in matched:
            for key, v in t["seconds"].items():
                seconds[key] = round(seconds.get(key, 0.0) + v, 3)
            for key, n in t["points_per_level"].items():
                per_level[key] = per_level.get(key, 0) + n
        added = {
            key: int(sum(t[key] for t in matched))
            for key in ("mpgc_failed", "edge_points", "edge_points_mpgc", "group1", "group3")
        }
        failed = added["mpgc_failed"]
        details = {
            "provenance": "coarse_to_fine",
            "tiles": len(first),
            "tiles_matched": len(matched),
            "levels": max(t["levels"] for t in matched),
            "points_per_level": per_level,
            "seconds": seconds,
            **added,
            "per_tile": [
                {key: t[key] for key in ("core", "points", "levels", "search_image_shifts_px")} for t in matched
            ],
        }
        stats = MatchStats(cls.name, list(s.ids), int(sum(counts)), details=details)
        progress.ensure(feedback).pushInfo(
            f"coarse-to-fine matching of {', '.join(s.names)}: {stats.points} "
            f"points, {failed} of them not accepted by MPGC (low reliability)"
        )
        return stats


def match_coarse_to_fine(
    images: Sequence[Any],
    models: Sequence[Any],
    names: Sequence[str] | None = None,
    params: CoarseToFineParams | None = None,
    height_range: GivenHeights = None,
    execution: Execution | None = None,
    feedback: Feedback | None = None,
) -> MultiPoints:
    """Coarse-to-fine multi-primitive matching with MPGC of 2 or 3 images (reference/nadir first, then the search
    images; paths, arrays or Images; block ids 1 ... n) with their sensor models, tile by tile on `execution`
    (threads by default), gathered in memory (tiled_rounds.match_in_memory). Returns MultiPoints (module
    docstring, step 5). Raises InputError on unusable input, CancelledError when cancelled."""
    return match_in_memory(
        CoarseToFine, StereoSet.of(images, models, names, heights=height_range), params, execution, feedback
    )
