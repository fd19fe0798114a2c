"""The matching step (pushbroom:matchpoints): dense image points of a block's stereo pair or triplet,
stored with the block.

The images are taken in combination order (combinations.combination_order: reference, forward[,
backward]) with their current sensor models, over the terrain height range (height_range.height_range:
the one given, else the block's). Strategy "region_growing": region-growing least-squares matching in
the three combinations of Kornus et al. 2006, section 3.3, tile by tile on the chosen execution
(block_tiles.match_tiles: memory follows the tile), seeded automatically, from the block's tie points,
or both. Strategy "coarse_to_fine": Zhang & Gruen's coarse-to-fine multi-primitive matching with MPGC
(coarse_to_fine.match_coarse_to_fine), in this process. Strategy "dense": semi-global matching of every
pixel (or every DenseParams.step px) of the reference image on epipolar tiles (dense.block_tiles), tile by
tile on the chosen execution, into the same point parts.

Storage: the points go to the sidecar folder <block>.mass_points.<id> (block/points.py; region growing's
tiles write its parts themselves, Block.store_points) and the block's 'mass_points' layer, placed
through the reference image's model at the mean height of the range; the points per group (Kornus et
al. 2006, Table 1) are counted part by part, logged and, when asked, written as CSV."""
import functools
from dataclasses import dataclass, field

from .. import progress
from ..block import Block
from ..block.points import load_arrays, read_stats, save_part
from ..dense.block_tiles import match_dense_tiles
from ..dense.params import DenseParams
from ..errors import InputError
from ..execution import Execution
from ..height_range import height_range, mean_height
from ..matching.block_tiles import match_tiles
from ..matching.coarse_to_fine import CoarseToFineParams, match_coarse_to_fine
from ..matching.combinations import combination_order, format_summary, summary_rows, write_summary_csv
from ..matching.params import GrowParams

#: seed sources of region growing: key -> (use the block's tie points, seek automatic seeds)
SEED_SOURCES = {"automatic": (False, True), "tie_points": (True, False), "both": (True, True)}
#: matching strategies
STRATEGIES = ("region_growing", "coarse_to_fine", "dense")


@dataclass
class MatchParams:
    """The matching step's settings; each is a pushbroom:matchpoints parameter."""

    images: str = ""                    # names in combination order (reference, forward[, backward]); "": all
    min_height: float = None            # m ellipsoidal; None: the block's terrain height range
    max_height: float = None            # m ellipsoidal; None: the block's terrain height range
    strategy: str = "region_growing"    # one of STRATEGIES
    seeds: str = "automatic"            # one of SEED_SOURCES (region growing)
    grow: GrowParams = field(default_factory=GrowParams)                            # region growing, LSM
    coarse_to_fine: CoarseToFineParams = field(default_factory=CoarseToFineParams)  # the second strategy
    dense: DenseParams = field(default_factory=DenseParams)                         # the third
    sigma_factor: float = 3.0           # group 3 consistency test: deviations below k robust sigma
    grow_second: bool = True            # also grow combination (b) where (a) found no points
    refine: bool = True                 # MPGC refinement of the group 3 points
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # region growing's, dense tiles

    def check(self):
        """Raise InputError for settings no matching can use."""
        if self.strategy not in STRATEGIES:
            raise InputError(f"the matching strategy must be one of {', '.join(STRATEGIES)}, got {self.strategy!r}")
        if self.seeds not in SEED_SOURCES:
            raise InputError(f"the seeds must be one of {', '.join(SEED_SOURCES)}, got {self.seeds!r}")
        if self.sigma_factor <= 0:
            raise InputError("the consistency factor must be positive")
        self.grow.check()
        self.dense.check()
        self.execution.check()
        return self


@dataclass
class MatchResult:
    """What match_block_points stored."""

    count: int                  # the points matched
    sidecar: str                # the mass point folder (block/points.py)
    layer: str                  # OGR source of the block's 'mass_points' layer
    summary: list               # points per group (combinations.summary_rows)
    summary_csv: str = None     # the summary CSV, where one was asked for


def match_block_points(block_path, params=None, summary_csv=None, feedback=None):
    """Match the images of the block at `block_path` with MatchParams `params` and store the mass points;
    `summary_csv`: where to write the points per group (None: nowhere). Returns a MatchResult. Raises
    InputError (settings, images not in the block, no tie points where asked for, no overlap, no points),
    CancelledError when cancelled."""
    params = (params or MatchParams()).check()
    log = progress.ensure(feedback)
    blk = Block(block_path)
    blk.check_writable("the matched points")        # before the matching, not after it
    rows = combination_order(blk.images(), params.images)
    models = list(blk.models([r["id"] for r in rows]).values())
    heights = height_range(params.min_height, params.max_height, blk.height_range())
    use_tie_points, automatic = SEED_SOURCES[params.seeds]
    seed_points = blk.points("tie_points") if use_tie_points else None
    log.pushInfo("combination order: " + ", ".join(r["name"] for r in rows) + f"; height range {heights}")
    images, names, ids = [r["image_path"] for r in rows], [r["name"] for r in rows], [r["id"] for r in rows]
    display = (models[0], rows[0]["id"], mean_height(heights))
    if params.strategy == "coarse_to_fine":
        if params.execution.backend != "threads":
            progress.warn(feedback, f"the coarse-to-fine matcher runs its tiles in this process: the "
                                    f"{params.execution.backend} execution applies to region growing only")
        result = match_coarse_to_fine(images, models, names=names, image_ids=ids,
                                      params=params.coarse_to_fine.check(), height_range=heights, feedback=feedback)
        # storage: the sidecar and the point layer
        sidecar = blk.save_points(result, "mass_points", display=display)
    elif params.strategy == "dense":
        def fill(folder):
            return match_dense_tiles(images, models, folder, save_part, names=names, image_ids=ids,
                                     params=params.dense, height_range=heights,
                                     feedback=progress.scaled(feedback, 0, 90), execution=params.execution)
        sidecar = blk.store_points("mass_points", fill, display=display, feedback=progress.scaled(feedback, 90, 100))
    else:
        def fill(folder):
            return match_tiles(images, models, folder, save_part, names=names, image_ids=ids, params=params.grow,
                               height_range=heights, seed_points=seed_points, automatic=automatic,
                               feedback=progress.scaled(feedback, 0, 90), execution=params.execution,
                               grow_second=params.grow_second, sigma_factor=params.sigma_factor, refine=params.refine)
        # storage: the tiles write the parts of the new sidecar, then the point layer is built
        sidecar = blk.store_points("mass_points", fill, display=display, feedback=progress.scaled(feedback, 90, 100))
    layer = blk.layer_source("mass_points")
    parts = blk.point_parts("mass_points")
    summary = summary_rows([functools.partial(load_arrays, p) for p in parts], stats=read_stats(sidecar))
    log.pushInfo("points per group (Kornus et al. 2006, Table 1):\n" + format_summary(summary))
    csv = write_summary_csv(summary_csv, summary) if summary_csv else None
    return MatchResult(dict(summary)["All points"], sidecar, layer, summary, csv)
