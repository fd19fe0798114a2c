"""The matching step (pushbroom:matchpoints): image points of a block's stereo pair or triplet, stored with the
block.

The images are taken in combination order (image_order.combination_order: reference, forward[, backward]) with
their current sensor models, over the terrain height range (height_range.height_range: the one given, else the
block's), as a StereoSet. The strategy is the one registered under MatchParams.strategy (matching/strategy.py;
the built-in ones: matching_strategies.py), with its settings; every strategy runs tile by tile on the chosen
execution (matching/tiled_rounds.py: memory follows the tile), its tiles writing the parts of the new point
folder.

Storage: the points go to the point folder <block>.mass_points.<id> (block/points.py, Block.store_point_parts) and
the block's 'mass_points' layer, placed through the reference image's model at the middle of the height range;
the points per group (Kornus et al. 2006, Table 1) are counted part by part, logged and, when asked, written as
CSV (group_summary.py). The stats record the strategy's spacing in the reference image: a run that finds far
fewer points than the block holds at that spacing (none, or below half: block/replacement.py) keeps them, unless
`replace_fewer`.

A height range given that misses the block's terrain heights (check_height_range) is said before matching:
entirely, an error where the block measured them (its DEM, or the height search at its creation), since the
rays would be searched where the terrain is not; mostly, a warning."""

import functools
from dataclasses import dataclass, field
from typing import Any, Optional

from .. import progress
from ..block import Block
from ..block.points import load_arrays, write_part
from ..errors import InputError
from ..execution import Execution
from ..height_range import height_range
from ..matching.group_summary import Rows, format_summary, summary_rows, write_summary_csv
from ..matching.image_order import combination_order
from ..matching.match_stats import MatchStats
from ..matching.stereo_set import StereoSet
from ..matching.tiled_rounds import match_in_tiles
from ..matching_strategies import strategy_named
from ..progress import Feedback

#: a given height range covering less than this share of the block's terrain heights is warned about
MOSTLY_MISSED = 0.5


@dataclass
class MatchParams:
    """The matching step's settings; each is a pushbroom:matchpoints parameter. `settings`: the strategy's
    settings object (its settings_type; None: its defaults)."""

    images: str = ""  # names in combination order (reference, forward[, backward]); "": all
    min_height: Optional[float] = None  # m ellipsoidal; None: the block's terrain height range
    max_height: Optional[float] = None  # m ellipsoidal; None: the block's terrain height range
    strategy: str = "region_growing"  # a registered strategy's name (matching/strategy.py)
    settings: Any = None
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))
    replace_fewer: bool = False  # replace the block's mass points even by far fewer (block/replacement.py)

    def check(self) -> "MatchParams":
        """Raise InputError for settings no matching can use; fills in the strategy's default settings."""
        self.settings = strategy_named(self.strategy).settings(self.settings)
        self.execution.check()
        return self


@dataclass
class MatchResult:
    """What match_block_points stored."""

    count: int  # the points matched
    folder: str  # the point folder (block/points.py)
    layer: str  # OGR source of the block's 'mass_points' layer
    summary: Rows  # points per group (group_summary.summary_rows)
    summary_csv: Optional[str] = None  # the summary CSV, where one was asked for


def match_block_points(
    block_path: str,
    params: Optional[MatchParams] = None,
    summary_csv: Optional[str] = None,
    feedback: Optional[Feedback] = None,
) -> MatchResult:
    """Match the images of the block at `block_path` with MatchParams `params` and store the mass points;
    `summary_csv`: where to write the points per group (None: nowhere). Returns a MatchResult. Raises
    InputError (settings, images not in the block, no tie points where asked for, a height range beside the
    block's measured terrain heights, no overlap, far fewer points than the block holds), CancelledError when
    cancelled."""
    params = (params or MatchParams()).check()
    strategy = strategy_named(params.strategy)
    log = progress.ensure(feedback)
    blk = Block(block_path)
    blk.check_writable("the matched points")  # before the matching, not after it
    rows = combination_order(blk.images(), params.images)
    ids = [r["id"] for r in rows]
    models = list(blk.models(ids).values())
    terrain = blk.height_range()
    stereo = StereoSet.of(
        [r["image_path"] for r in rows],
        models,
        [r["name"] for r in rows],
        ids,
        height_range(params.min_height, params.max_height, terrain),
        functools.partial(blk.points, "tie_points"),
    )
    if terrain is not None and (params.min_height is not None or params.max_height is not None):
        check_height_range(stereo.heights.bounds, terrain, terrain_source(blk.info()), feedback)
    log.pushInfo("combination order: " + ", ".join(stereo.names) + f"; height range {stereo.heights.bounds}")
    spacing = strategy.spacing(params.settings)

    def fill(folder: str) -> tuple[list, dict]:
        entries, stats = match_in_tiles(
            strategy, stereo, params.settings, folder, write_part, params.execution, progress.scaled(feedback, 0, 90)
        )
        stats.spacing_px = spacing  # block/points.SPACING: the store compares at it
        return entries, stats.as_dict()

    folder = blk.store_point_parts(
        "mass_points",
        fill,
        display=(models[0], ids[0], stereo.heights.mean),
        feedback=progress.scaled(feedback, 90, 100),
        replace_fewer=params.replace_fewer,
    )
    layer = blk.layer_source("mass_points")
    summary = summary_rows(
        [functools.partial(load_arrays, p) for p in blk.point_parts("mass_points")],
        stats=MatchStats.from_dict(blk.point_stats("mass_points")),
    )
    log.pushInfo("points per group (Kornus et al. 2006, Table 1):\n" + format_summary(summary))
    csv = write_summary_csv(summary_csv, summary) if summary_csv else None
    return MatchResult(int(dict(summary)["All points"]), folder, layer, summary, csv)


def terrain_source(info: dict) -> tuple[str, bool]:
    """Where the block's terrain height range comes from, given its block_info `info`: (text, measured)."""
    if info.get("footprint_height") == "dem":
        return "its DEM", True
    if "height_search" in info:
        return "matching at its creation", True
    return "the mean height it was created at, +- 500 m", False


def check_height_range(
    searched: tuple[float, float],
    terrain: tuple[float, float],
    source: tuple[str, bool],
    feedback: Feedback | None = None,
) -> None:
    """Say where the height range `searched` (h_min, h_max; m) misses the block's terrain heights `terrain`
    (h_min, h_max) from `source` (terrain_source): entirely (no overlap), an InputError where the block
    measured its heights, else a warning; mostly (the overlap is less than MOSTLY_MISSED of the terrain's
    range), a warning. Matching finds points only at heights it searches."""
    (lo, hi), (t_lo, t_hi), (where, measured) = searched, terrain, source
    text = (
        f"the heights searched, {lo:.0f} to {hi:.0f} m (from MIN_HEIGHT, MAX_HEIGHT), {{}} the block's "
        f"terrain heights, {t_lo:.0f} to {t_hi:.0f} m (from {where})"
    )
    if hi < t_lo or lo > t_hi:
        message = (
            text.format("miss") + ": matching would find no point there, or wrong ones. Give a range that "
            "overlaps the terrain, or leave MIN_HEIGHT and MAX_HEIGHT empty to use the block's"
        )
        if measured:
            raise InputError(message)
        progress.warn(feedback, message)
        return
    share = (min(hi, t_hi) - max(lo, t_lo)) / (t_hi - t_lo) if t_hi > t_lo else 1.0
    if share < MOSTLY_MISSED:
        progress.warn(
            feedback, text.format(f"cover only {share:.0%} of") + ": points at the other heights are not found"
        )
