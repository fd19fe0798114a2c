"""The block creation step (pushbroom:createblock): images and their supplied orientation into a new
block GeoPackage.

`create_block(output, images, params, feedback)` opens each image's sensor model (Block.open_images:
SPOT 1-5 DIMAP, RPC tags or _RPC.TXT/.RPB files, OSSIM .geom; the orientation files found beside the
images unless given, one per image in the same order), reads the optional DEM (ellipsoidal heights;
implausible heights are warned about, a void value can be declared as nodata) and stores the block
(Block.create: footprints on the DEM or at the mean height, the terrain height range). An existing
block is only replaced with `overwrite`."""
from dataclasses import dataclass, field
from typing import Optional

from .. import progress
from ..atomic import work_dir
from ..block import Block
from ..dem_store import store_dem


@dataclass
class CreateParams:
    """The creation's settings; each is a pushbroom:createblock parameter."""

    orientation: list = field(default_factory=list)   # orientation files, one per image; empty: beside them
    dem: Optional[str] = None           # DEM for the footprints (ellipsoidal heights)
    dem_nodata: Optional[float] = None  # void value of the DEM its file does not flag
    height: float = 0.0                 # mean ellipsoidal height without a DEM (m)
    overwrite: bool = False             # replace an existing block


@dataclass
class CreateResult:
    """The block created."""

    path: str
    footprints: str     # OGR source of its footprint layer
    images: list        # (name, columns, rows) per image, in block order


def create_block(output, images, params, feedback=None):
    """Create the block `output` (.gpkg) from the image rasters `images` with CreateParams `params`;
    returns a CreateResult. Raises InputError (no or duplicate images, orientation files that do not
    match, an existing block without overwrite, a footprint that cannot be projected) and the sensor
    readers' errors."""
    opened = Block.open_images(images, [p for p in params.orientation if p])
    with work_dir(output, "the stored DEM") as work:
        dem = None
        if params.dem:
            dem = store_dem(params.dem, work, params.dem_nodata)
            progress.warn(feedback, dem.implausible)
        # storage: the new block
        blk = Block.create(output, opened, height=params.height, dem=dem, overwrite=params.overwrite,
                           feedback=feedback)
    progress.ensure(feedback).pushInfo(f"block {output}: " + ", ".join(
        f"{name} ({model.size[0]} x {model.size[1]})" for name, _, _, model in opened))
    return CreateResult(output, blk.layer_source("footprints"),
                        [(name, model.size[0], model.size[1]) for name, _, _, model in opened])
