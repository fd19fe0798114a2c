"""The block creation step (pushbroom:createblock): images and their supplied orientation into a new
block GeoPackage.

`create_block(output, images, params, feedback)` opens each image's sensor model (Block.open_images:
SPOT 1-5 DIMAP, RPC tags or _RPC.TXT/.RPB files, OSSIM .geom; the orientation files found beside the
images unless given, one per image in the same order), reads the optional DEM (ellipsoidal heights;
implausible heights are warned about, a void value can be declared as nodata) and stores the block
(Block.create: footprints on the DEM or at the mean height, the terrain height range). An existing
block is only replaced with `overwrite`.

The terrain height range comes from the DEM; else from the mean height given (+- 500 m); else, with two or
more images, it is found by matching (matching/height_search.py: sparse points over the orientation's whole
valid height range, intersected; the footprints at their median height); a single image without either
takes its orientation's mean height (an RPC's HEIGHT_OFF; 0 m for a SPOT model), with a warning."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .. import progress
from ..atomic import work_dir
from ..block import Block
from ..block.images import check_new_block
from ..dem_store import store_dem
from ..errors import InputError
from ..execution import Execution
from ..height_range import check_height
from ..matching.height_search import HeightSearch, search_heights, validity_range

if TYPE_CHECKING:
    from ..block.images import ImageEntry
    from ..progress import Feedback


@dataclass
class CreateParams:
    """The creation's settings; each is a pushbroom:createblock parameter."""

    orientation: list[str] = field(default_factory=list)  # orientation files, one per image; empty: beside them
    dem: str | None = None  # DEM for the footprints (ellipsoidal heights)
    dem_nodata: float | None = None  # void value of the DEM its file does not flag
    height: float | None = None  # mean ellipsoidal height without a DEM (m); None: found by matching
    overwrite: bool = False  # replace an existing block
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # where the height search runs


@dataclass
class CreateResult:
    """The block created."""

    path: str
    footprints: str  # OGR source of its footprint layer
    images: list[tuple[str, int, int]]  # (name, columns, rows) per image, in block order


def create_block(
    output: str, images: Sequence[str], params: CreateParams, feedback: Feedback | None = None
) -> CreateResult:
    """Create the block `output` (.gpkg) from the image rasters `images` with CreateParams `params`;
    returns a CreateResult. Raises InputError (no or duplicate images, orientation files that do not
    match, a mean height outside height_range.PLAUSIBLE_HEIGHTS, an existing block without overwrite, a
    footprint that cannot be projected) and the sensor readers' errors."""
    check_height(params.height, "the mean terrain height (HEIGHT)")
    check_new_block(output, params.overwrite)
    opened = Block.open_images(images, [p for p in params.orientation if p])
    with work_dir(output, "the stored DEM") as work:
        dem = None
        if params.dem:
            dem = store_dem(params.dem, work, params.dem_nodata)
            progress.warn(feedback, dem.implausible)
        height = params.height
        heights: tuple[float, float] | None = None
        found: HeightSearch | None = None
        if dem is None and height is None:
            height, heights, found = _terrain_heights(opened, params.execution, feedback)
        # storage: the new block
        blk = Block.create(
            output,
            opened,
            height=height,
            dem=dem,
            overwrite=params.overwrite,
            feedback=progress.scaled(feedback, 80, 100) if found else feedback,
            height_range=heights,
        )
        if found:
            blk.update_info(
                {
                    "height_search": f"{found.points} points matched over {found.searched[0]:.0f} to "
                    f"{found.searched[1]:.0f} m, {found.rejected} rejected"
                }
            )
    progress.ensure(feedback).pushInfo(
        f"block {output}: " + ", ".join(f"{name} ({model.size[0]} x {model.size[1]})" for name, _, _, model in opened)
    )
    return CreateResult(
        output, blk.layer_source("footprints"), [(name, model.size[0], model.size[1]) for name, _, _, model in opened]
    )


def _terrain_heights(
    opened: Sequence[ImageEntry], execution: Execution, feedback: Feedback | None
) -> tuple[float, tuple[float, float] | None, HeightSearch | None]:
    """(footprint height, terrain height range or None, HeightSearch or None) of a block made without a DEM
    and without a height (module docstring)."""
    names, paths, models = [o[0] for o in opened], [o[1] for o in opened], [o[3] for o in opened]
    log = progress.ensure(feedback)
    if len(opened) < 2:
        height = getattr(models[0], "height_range", None)
        height = 0.5 * (height[0] + height[1]) if height else 0.0
        progress.warn(
            feedback,
            f"no DEM and no height given: the footprint of {names[0]} is at its orientation's "
            f"mean height {height:.0f} m +- 500 m; give a DEM or a mean height for a better one",
        )
        return height, None, None
    if not all(paths):
        raise InputError(
            "no DEM and no height given, and the terrain height cannot be found without the images' "
            "pixels: give a DEM or a mean height"
        )
    lo, hi = validity_range(models)
    log.pushInfo(
        f"no DEM and no height given: finding the terrain height by matching {names[0]} with "
        f"{', '.join(names[1:])} over the orientation's valid heights {lo:.0f} to {hi:.0f} m"
    )
    found = search_heights(paths, models, names, progress.scaled(feedback, 0, 80), execution)
    log.pushInfo(
        f"terrain heights {found.height_range[0]:.0f} to {found.height_range[1]:.0f} m (median "
        f"{found.median:.0f} m) from {found.points} matched points ({found.rejected} rejected as mismatches)"
    )
    return found.median, found.height_range, found
