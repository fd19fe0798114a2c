"""The tie point selection step (pushbroom:selecttiepoints): tie points for the bundle adjustment
chosen from the block's mass points (tiepoints.select_tie_points; Kornus et al. 2006 section 3.3) and
stored with the block: the sidecar <block>.tie_points.npz referenced in block_info, and the point layer
'tie_points' placed through the reference image's model at the block's mean terrain height."""
from dataclasses import dataclass

from .. import block, progress
from ..height_range import mean_height
from . import points
from .tiepoints import select_tie_points


@dataclass
class TieParams:
    """The selection's settings; each is a pushbroom:selecttiepoints parameter."""

    cell: float = 100.0     # grid cell size, px of the reference image
    min_group: int = 1      # lowest point group accepted (1, 2 or 3)


@dataclass
class TieResult:
    """What select_block_tie_points stored."""

    count: int      # tie points selected
    sidecar: str    # the tie point file (.npz)
    layer: str      # OGR source of the block's 'tie_points' layer


def select_block_tie_points(block_path, params, feedback=None):
    """Select and store the tie points of the block at `block_path` with TieParams `params`; returns a
    TieResult. Raises InputError (a cell size that is not positive, no mass points)."""
    mass = points.load_points(block_path, "mass_points")
    tie = select_tie_points(mass, cell=params.cell, min_group=params.min_group)
    reference = tie.stats.get("tie_reference", (mass.stats.get("images") or [1])[0])
    progress.ensure(feedback).pushInfo(f"{len(tie)} tie points from {len(mass)} mass points: "
                                       + ", ".join(f"group {g}: {n}" for g, n in tie.group_counts().items()))
    # storage: the sidecar and the point layer
    npz = points.save_points(block_path, tie, "tie_points", display=(
        block.load_model(block_path, reference), reference, mean_height(block.height_range(block_path))))
    return TieResult(len(tie), npz, points.layer_source(block_path, "tie_points"))
