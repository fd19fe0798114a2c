"""The tie point selection step (pushbroom:selecttiepoints): tie points for the bundle adjustment
chosen from the block's mass points (tiepoints.select_tie_points; Kornus et al. 2006 section 3.3) and
stored with the block: the sidecar folder <block>.tie_points.<id> referenced in block_info, and the point layer
'tie_points' placed through the reference image's model at the block's mean terrain height."""
from dataclasses import dataclass

from .. import progress
from ..block import Block
from ..height_range import mean_height
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
    mass = blk.points("mass_points")
    tie = select_tie_points(mass, cell=params.cell, min_group=params.min_group)
    reference = tie.stats.get("tie_reference", (mass.stats.get("images") or [1])[0])
    progress.ensure(feedback).pushInfo(f"{len(tie)} tie points from {len(mass)} mass points: "
                                       + ", ".join(f"group {g}: {n}" for g, n in tie.group_counts().items()))
    # storage: the sidecar and the point layer
    npz = blk.save_points(tie, "tie_points", display=(blk.model(reference), reference, mean_height(blk.height_range())))
    return TieResult(len(tie), npz, blk.layer_source("tie_points"))
