"""The orthorectification step (pushbroom:orthorectify): one image, with a block's (adjusted) sensor model or
its own orientation, on a DEM, by ortho.orthorectify (the indirect method, Heipke et al. 1992, section 4.1).

The orthoimage covers the image only where the DEM has heights: a DEM that leaves part of the image out
(ortho.grid.dem_coverage below FULL_COVERAGE) is a warning with the share it covers."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from .. import progress, sensors
from ..atomic import work_dir
from ..block import Block
from ..dem_store import VERTICAL, store_dem
from ..errors import InputError
from ..execution import Execution
from ..ortho.grid import dem_coverage
from ..ortho.orthorectify import OrthoOutputs, OrthoSettings, orthorectify
from ..ortho.resampling import METHODS

if TYPE_CHECKING:
    from ..ortho.orthorectify import OrthoResult
    from ..progress import Feedback
    from ..sensors.base import SensorModel

#: the share of the image under DEM heights below which the step warns that the orthoimage is partial
FULL_COVERAGE = 0.98


@dataclass
class OrthoParams:
    """The orthorectification step's settings (pushbroom:orthorectify); see orthorectify and dem_store.store_dem."""

    dem_heights: str = "ellipsoidal"  # one of VERTICAL
    dem_nodata: float | None = None  # a void value of the DEM declared as nodata
    crs: str | None = None  # output CRS (authority id or WKT); None: the UTM zone of the footprint
    cell_size: float | None = None  # CRS units; None: the image's ground sampling distance
    resampling: str = "bilinear"  # one of resampling.METHODS
    occlusion: bool = False  # occluded cells as nodata
    max_error: float = 0.01  # px: bound of the coarse-grid interpolation error
    cog: bool = False  # the orthoimage as a Cloud-Optimised GeoTIFF
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # where the tiles run

    def check(self) -> OrthoParams:
        """Raise InputError for settings no orthorectification can use."""
        if self.dem_heights not in VERTICAL or self.resampling not in METHODS:
            raise InputError(
                f"the DEM heights must be one of {', '.join(VERTICAL)} and the resampling one of {', '.join(METHODS)}"
            )
        if not self.max_error > 0 or (self.cell_size is not None and self.cell_size < 0):
            raise InputError("the error bound must be positive and the cell size not negative")
        self.execution.check()
        return self


def image_and_model(
    block_path: str | None = None, image_name: str | None = "", image: str | None = None, orientation: str | None = None
) -> tuple[str, SensorModel]:
    """(image path, sensor model): the block's (adjusted) model of the image named `image_name`, or,
    without a block, raster `image` with its own orientation (sensors.load: `orientation`, else the
    metadata found beside the image). InputError where neither is given, the name is not the block's or the
    image does not exist (sensors.check_image)."""
    if block_path:
        blk = Block(block_path)
        rows = blk.images()
        chosen = [r for r in rows if r["name"] == (image_name or "").strip()]
        if not chosen:
            raise InputError(
                f"the block has no image {(image_name or '').strip()!r}: give the name of one of its "
                f"images ({', '.join(r['name'] for r in rows)})"
            )
        sensors.check_image(chosen[0]["image_path"])  # moved or deleted since the block was made
        return chosen[0]["image_path"], blk.model(chosen[0]["id"])
    if not image:
        raise InputError("give a block and an image name, or an image")
    return image, sensors.load(orientation or image, image=image if orientation else None)


def orthorectify_image(
    output: str | OrthoOutputs,
    dem: str,
    params: OrthoParams | None = None,
    block_path: str | None = None,
    image_name: str | None = "",
    image: str | None = None,
    orientation: str | None = None,
    feedback: Feedback | None = None,
) -> OrthoResult:
    """The orthorectification step: the image chosen as in image_and_model on the raster DEM `dem`
    (dem_store.store_dem with the params' heights and nodata, in a work folder beside the output; implausible
    heights are reported), written to the
    GeoTIFF `output` (a path, or OrthoOutputs: with the occlusion mask, on a DSM the true orthoimage's hidden cells
    flagged) with OrthoParams `params`. Returns the OrthoResult."""
    params = (params or OrthoParams()).check()
    path, model = image_and_model(block_path, image_name, image, orientation)
    with work_dir(output.image if isinstance(output, OrthoOutputs) else output, "the stored DEM") as work:
        heights = store_dem(dem, work, params.dem_nodata, params.dem_heights)
        progress.warn(feedback, heights.implausible)
        covered = dem_coverage(model, heights)
        if covered < FULL_COVERAGE:
            progress.warn(
                feedback,
                f"the DEM {dem} has heights under {covered:.0%} of the image {path} only: the "
                "orthoimage covers that part (the rest lies outside the DEM or on its nodata); "
                "give a DEM that covers the whole image for a whole orthoimage",
            )
        return orthorectify(
            path,
            model,
            heights,
            output,
            settings=OrthoSettings(
                crs=params.crs,
                cell_size=params.cell_size,
                resampling_method=params.resampling,
                occluded_nodata=params.occlusion,
                max_error=params.max_error,
                cog=params.cog,
            ),
            execution=params.execution,
            feedback=feedback,
        )
