"""The tie point selection step (pushbroom:selecttiepoints): tie points for the bundle adjustment
chosen from the block's mass points (tiepoints.select_tie_points; Kornus et al. 2006 section 3.3), read
part by part (the best point of a cell is the best of each part's best), and
stored with the block: the point folder <block>.tie_points.<id> referenced in block_info, and the point layer
'tie_points' placed through the reference image's model at the block's mean terrain height.

Empty mass points, or none of the lowest group accepted, are refused before anything is stored; a selection
far fewer than the block's tie points (block/replacement.py: none, or below half of what the stored ones
give at the new CELL) keeps them unless `replace_fewer`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import progress
from ..block import Block
from ..block.points import MAKERS, load_arrays
from ..errors import InputError
from ..height_range import mean_height
from ..matching.points import MultiPoints
from ..matching.tiepoints import select_tie_points

if TYPE_CHECKING:
    from ..progress import Feedback


@dataclass
class TieParams:
    """The selection's settings; each is a pushbroom:selecttiepoints parameter."""

    cell: float = 100.0  # grid cell size, px of the reference image
    min_group: int = 1  # lowest point group accepted (1, 2 or 3)
    replace_fewer: bool = False  # replace the block's tie points even by far fewer (block/replacement.py)


@dataclass
class TieResult:
    """What select_block_tie_points stored."""

    count: int  # tie points selected
    folder: str  # the tie point folder (block/points.py)
    layer: str  # OGR source of the block's 'tie_points' layer


def select_block_tie_points(block_path: str, params: TieParams, feedback: Feedback | None = None) -> TieResult:
    """Select and store the tie points of the block at `block_path` with TieParams `params`; returns a
    TieResult. Raises InputError (a cell size that is not positive, no or empty mass points, none of group
    `min_group` or higher, far fewer tie points than the block holds)."""
    blk = Block(block_path)
    blk.check_writable("the tie points")
    parts = blk.point_parts("mass_points")
    stats = blk.point_stats("mass_points")
    reference = None
    if stats.get("images"):
        reference = int(stats["images"][0])
    # the best point of a cell is the best of the parts' best: the parts are read one at a time
    candidates, count, groups = [], 0, {1: 0, 2: 0, 3: 0}
    for path in parts:
        part = load_arrays(path)
        count += len(part)
        counts = part.group_counts()
        groups = {g: n + counts[g] for g, n in groups.items()}
        if reference is None and len(part.observations):
            reference = int(part.image_ids().min())
        if reference is not None:
            candidates.append(
                select_tie_points(part, cell=params.cell, reference_image_id=reference, min_group=params.min_group)
            )
    check_groups(groups, params.min_group)
    merged = MultiPoints(
        np.concatenate([c.points for c in candidates]) if candidates else None,
        np.concatenate([c.observations for c in candidates]) if candidates else None,
        stats,
    )
    tie = select_tie_points(merged, cell=params.cell, reference_image_id=reference, min_group=params.min_group)
    shown: int = tie.stats.get("tie_reference", reference or 1)  # the image the layer is placed through
    progress.ensure(feedback).pushInfo(
        f"{len(tie)} tie points from {count} mass points: "
        + ", ".join(f"group {g}: {n}" for g, n in tie.group_counts().items())
    )
    # storage: the point folder and the point layer
    folder = blk.store_points(
        tie,
        "tie_points",
        display=(blk.model(shown), shown, mean_height(blk.height_range())),
        feedback=feedback,
        replace_fewer=params.replace_fewer,
    )
    return TieResult(len(tie), folder, blk.layer_source("tie_points"))


def check_groups(groups: dict, min_group: int) -> None:
    """Refuse (InputError) mass points with {group: count} `groups` of which none is a candidate of group
    `min_group` or higher: there would be no tie point."""
    counts = ", ".join(f"group {g}: {n}" for g, n in groups.items())
    if not sum(groups.values()):
        raise InputError(
            f"the block's mass points are empty ({MAKERS['mass_points']} found none): nothing to select "
            "tie points from; match the block again with other settings"
        )
    if not sum(n for g, n in groups.items() if g >= min_group):
        highest = max(g for g, n in groups.items() if n)
        raise InputError(
            f"the block's mass points have no point of group {min_group} or higher ({counts}; group 1 "
            "are two-ray points, groups 2 and 3 three-ray points of a triplet): there are no tie points "
            f"to select. Set MIN_GROUP to {highest} or lower, or match three images "
            f"({MAKERS['mass_points']})"
        )
