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
al. 2006, Table 1) are counted part by part, logged and, when asked, written as CSV. The stats record the
strategy's spacing in the reference image (MatchParams.spacing): a run that finds far fewer points than the
block holds at that spacing (none, or below half: block/replacement.py) keeps them, unless `replace_fewer`.

A height range given that misses the block's terrain heights (check_height_range) is said before matching:
entirely, an error where the block measured them (its DEM, or the height search at its creation), since the
rays would be searched where the terrain is not; mostly, a warning."""
import functools
from dataclasses import dataclass, field
from typing import Optional

from .. import progress
from ..block import Block
from ..block.points import SPACING, load_arrays, read_stats, save_part
from ..dense.block_tiles import match_dense_tiles
from ..dense.params import DenseParams
from ..errors import InputError
from ..execution import Execution
from ..height_range import height_range, mean_height
from ..matching.block_tiles import match_tiles
from ..matching.coarse_to_fine import CoarseToFineParams, match_coarse_to_fine
from ..matching.combinations import combination_order, format_summary, summary_rows, write_summary_csv
from ..matching.pair_geometry import resolve_height_range
from ..matching.params import GrowParams

#: seed sources of region growing: key -> (use the block's tie points, seek automatic seeds)
SEED_SOURCES = {"automatic": (False, True), "tie_points": (True, False), "both": (True, True)}
#: matching strategies
STRATEGIES = ("region_growing", "coarse_to_fine", "dense")
#: a given height range covering less than this share of the block's terrain heights is warned about
MOSTLY_MISSED = 0.5


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
    replace_fewer: bool = False         # replace the block's mass points even by far fewer (block/replacement.py)

    def spacing(self) -> float:
        """The strategy's spacing of the points in the reference image (px): region growing's STEP, the
        coarse-to-fine grid, the dense lattice step."""
        return float({"region_growing": self.grow.step, "coarse_to_fine": self.coarse_to_fine.grid,
                      "dense": self.dense.step}[self.strategy])

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


def match_block_points(block_path: str, params: Optional[MatchParams] = None, summary_csv: Optional[str] = None,
                       feedback=None) -> MatchResult:
    """Match the images of the block at `block_path` with MatchParams `params` and store the mass points;
    `summary_csv`: where to write the points per group (None: nowhere). Returns a MatchResult. Raises
    InputError (settings, images not in the block, no tie points where asked for, a height range beside the
    block's measured terrain heights, no overlap, far fewer points than the block holds), CancelledError when
    cancelled."""
    params = (params or MatchParams()).check()
    log = progress.ensure(feedback)
    blk = Block(block_path)
    blk.check_writable("the matched points")        # before the matching, not after it
    rows = combination_order(blk.images(), params.images)
    models = list(blk.models([r["id"] for r in rows]).values())
    terrain = blk.height_range()
    heights = height_range(params.min_height, params.max_height, terrain)
    if terrain is not None and (params.min_height is not None or params.max_height is not None):
        check_height_range(resolve_height_range(models[0], heights), terrain, terrain_source(blk.info()), feedback)
    use_tie_points, automatic = SEED_SOURCES[params.seeds]
    seed_points = blk.points("tie_points") if use_tie_points else None
    log.pushInfo("combination order: " + ", ".join(r["name"] for r in rows) + f"; height range {heights}")
    images, names, ids = [r["image_path"] for r in rows], [r["name"] for r in rows], [r["id"] for r in rows]
    display = (models[0], rows[0]["id"], mean_height(heights))
    spacing = {SPACING["mass_points"]: params.spacing()}       # in the stats: the store compares at it
    store = functools.partial(blk.store_points, "mass_points", display=display,
                              feedback=progress.scaled(feedback, 90, 100), replace_fewer=params.replace_fewer)
    if params.strategy == "coarse_to_fine":
        if params.execution.backend != "threads":
            progress.warn(feedback, f"the coarse-to-fine matcher runs its tiles in this process: the "
                                    f"{params.execution.backend} execution applies to region growing only")
        result = match_coarse_to_fine(images, models, names=names, image_ids=ids,
                                      params=params.coarse_to_fine.check(), height_range=heights, feedback=feedback)
        result.stats.update(spacing)
        # storage: the sidecar and the point layer
        sidecar = blk.save_points(result, "mass_points", display=display, feedback=progress.quiet(feedback),
                                  replace_fewer=params.replace_fewer)
    elif params.strategy == "dense":
        def fill(folder):
            entries, stats = match_dense_tiles(images, models, folder, save_part, names=names, image_ids=ids,
                                               params=params.dense, height_range=heights,
                                               feedback=progress.scaled(feedback, 0, 90), execution=params.execution)
            return entries, {**stats, **spacing}
        sidecar = store(fill)
    else:
        def fill(folder):
            entries, stats = match_tiles(
                images, models, folder, save_part, names=names, image_ids=ids, params=params.grow,
                height_range=heights, seed_points=seed_points, automatic=automatic,
                feedback=progress.scaled(feedback, 0, 90), execution=params.execution, grow_second=params.grow_second,
                sigma_factor=params.sigma_factor, refine=params.refine)
            return entries, {**stats, **spacing}
        # storage: the tiles write the parts of the new sidecar, then the point layer is built
        sidecar = store(fill)
    layer = blk.layer_source("mass_points")
    parts = blk.point_parts("mass_points")
    summary = summary_rows([functools.partial(load_arrays, p) for p in parts], stats=read_stats(sidecar))
    log.pushInfo("points per group (Kornus et al. 2006, Table 1):\n" + format_summary(summary))
    csv = write_summary_csv(summary_csv, summary) if summary_csv else None
    return MatchResult(dict(summary)["All points"], sidecar, layer, summary, csv)


def terrain_source(info: dict) -> tuple[str, bool]:
    """Where the block's terrain height range comes from, given its block_info `info`: (text, measured)."""
    if info.get("footprint_height") == "dem":
        return "its DEM", True
    if "height_search" in info:
        return "matching at its creation", True
    return "the mean height it was created at, +- 500 m", False


def check_height_range(searched: tuple[float, float], terrain: tuple[float, float], source: tuple[str, bool],
                       feedback=None) -> None:
    """Say where the height range `searched` (h_min, h_max; m) misses the block's terrain heights `terrain`
    (h_min, h_max) from `source` (terrain_source): entirely (no overlap), an InputError where the block
    measured its heights, else a warning; mostly (the overlap is less than MOSTLY_MISSED of the terrain's
    range), a warning. Matching finds points only at heights it searches."""
    (lo, hi), (t_lo, t_hi), (where, measured) = searched, terrain, source
    text = (f"the heights searched, {lo:.0f} to {hi:.0f} m (from MIN_HEIGHT, MAX_HEIGHT), {{}} the block's "
            f"terrain heights, {t_lo:.0f} to {t_hi:.0f} m (from {where})")
    if hi < t_lo or lo > t_hi:
        message = (text.format("miss") + ": matching would find no point there, or wrong ones. Give a range that "
                   "overlaps the terrain, or leave MIN_HEIGHT and MAX_HEIGHT empty to use the block's")
        if measured:
            raise InputError(message)
        progress.warn(feedback, message)
        return
    share = (min(hi, t_hi) - max(lo, t_lo)) / (t_hi - t_lo) if t_hi > t_lo else 1.0
    if share < MOSTLY_MISSED:
        progress.warn(feedback, text.format(f"cover only {share:.0%} of") + ": points at the other heights are "
                                "not found")
