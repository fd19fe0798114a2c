"""The tie point selection step (pushbroom:selecttiepoints): tie points for the bundle adjustment
chosen from the block's mass points (tiepoints.select_tie_points; Kornus et al. 2006 section 3.3), read
part by part (the best point of a cell is the best of each part's best), and
stored with the block: the sidecar folder <block>.tie_points.<id> referenced in block_info, and the point layer
'tie_points' placed through the reference image's model at the block's mean terrain height."""
from dataclasses import dataclass

import numpy as np

from .. import progress
from ..block import Block
from ..block.points import load_arrays
from ..height_range import mean_height
from ..matching.points import MultiPoints
from ..matching.tiepoints import select_tie_points


@dataclass
class TieParams:
    """The selection's settings; each is a pushbroom:selecttiepoints parameter."""

    cell: float = 100.0     # grid cell size, px of the reference image
    min_group: int = 1      # lowest point group accepted (1, 2 or 3)


@dataclass
class TieResult:
    """What select_block_tie_points stored."""

    count: int      # tie points selected
    sidecar: str    # the tie point folder (block/points.py)
    layer: str      # OGR source of the block's 'tie_points' layer


def select_block_tie_points(block_path, params, feedback=None):
    """Select and store the tie points of the block at `block_path` with TieParams `params`; returns a
    TieResult. Raises InputError (a cell size that is not positive, no mass points)."""
    blk = Block(block_path)
    blk.check_writable("the tie points")
    parts = blk.point_parts("mass_points")
    stats = blk.point_stats("mass_points")
    reference = None
    if stats.get("images"):
        reference = int(stats["images"][0])
    # the best point of a cell is the best of the parts' best: the parts are read one at a time
    candidates, count = [], 0
    for path in parts:
        part = load_arrays(path)
        count += len(part)
        if reference is None and len(part.observations):
            reference = int(part.image_ids().min())
        if reference is not None:
            candidates.append(select_tie_points(part, cell=params.cell, reference_image_id=reference,
                                                min_group=params.min_group))
    merged = MultiPoints(np.concatenate([c.points for c in candidates]) if candidates else None,
                         np.concatenate([c.observations for c in candidates]) if candidates else None, stats)
    tie = select_tie_points(merged, cell=params.cell, reference_image_id=reference, min_group=params.min_group)
    reference = tie.stats.get("tie_reference", reference or 1)
    progress.ensure(feedback).pushInfo(f"{len(tie)} tie points from {count} mass points: "
                                       + ", ".join(f"group {g}: {n}" for g, n in tie.group_counts().items()))
    # storage: the sidecar and the point layer
    sidecar = blk.save_points(tie, "tie_points", display=(blk.model(reference), reference,
                                                          mean_height(blk.height_range())))
    return TieResult(len(tie), sidecar, blk.layer_source("tie_points"))
