"""The RPC fitting step (pushbroom:fitrpc): RPC00B fitted to the sensor models a block holds
(sensors/rpc_fit.py; Kornus et al. 2006 section 3.5.2), written as _RPC.TXT files GDAL reads.

`fit_block_rpcs(block_path, params, feedback)` fits one RPC per chosen image over the cube's height
range (both heights given, within height_range.PLAUSIBLE_HEIGHTS, or the block's terrain height range widened
by rpc_fit.default_height_range; a cube that leaves out some of the block's terrain is a warning), writes
<image stem>_RPC.TXT beside each raster or <image name>_RPC.TXT into a folder (every destination is checked
before the first fit), compares the object points of the block's tie points intersected
with the RPCs and with the rigorous models (surface.intersection.height_differences; Kornus et al.
2006 Table 5) when RPCs were fitted for all their images, and records the step in the block's
history.

Beside the rasters, a _RPC.TXT is what GDAL reads as the raster's RPC, before the RPC in the raster's own
metadata (GeoTIFF tags) and after a .RPB beside it. So where GDAL finds an RPC of the raster's own
(rpc_fit.raster_rpc_source: its metadata, a .RPB or a _RPC.TXT), writing beside it replaces or shadows the
image's supplied orientation for every GDAL program and for any block made from it later: refused unless
`overwrite`, and then a warning says which RPC GDAL reads. A raster without an RPC (a SPOT DIMAP product's)
gets its fitted RPC beside it by default, so that GDAL programs use the block's orientation."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress
from ..adjustment import report
from ..block import Block
from ..errors import InputError
from ..height_range import check_heights, mean_height
from ..sensors import rpc_fit
from ..surface.intersection import height_differences

if TYPE_CHECKING:
    from ..progress import Feedback
    from ..sensors.rpc import RpcModel


@dataclass
class RpcParams:
    """The RPC fit's settings; each is a pushbroom:fitrpc parameter."""

    image: str = ""  # image name; empty: every image of the block
    min_height: float | None = None  # cube heights (m, ellipsoidal); both or neither
    max_height: float | None = None
    overwrite: bool = False  # replace existing _RPC.TXT files, shadow a raster's own RPC
    grid: int = rpc_fit.DEFAULT_GRID[0]  # image grid points along columns and rows
    height_levels: int = rpc_fit.DEFAULT_GRID[2]
    folder: str | None = None  # output folder; None: beside each image raster
    report: str | None = None  # HTML report path

    def check(self) -> RpcParams:
        """Raise InputError for settings the fit cannot use."""
        if self.grid < 4 or self.height_levels < 4:
            raise InputError(
                f"the RPC cube needs at least 4 grid points and 4 height levels, not {self.grid} and "
                f"{self.height_levels}"
            )
        return self


@dataclass
class RpcResult:
    """The files fit_block_rpcs wrote."""

    files: list[str] = field(default_factory=list)  # the _RPC.TXT files, in the order of the images
    report: str | None = None


def selected_images(rows: Sequence[dict[str, Any]], name: str | None) -> list[dict[str, Any]]:
    """The block's image rows, or the one called `name` (empty: all)."""
    name = (name or "").strip()
    if not name:
        return list(rows)
    chosen = [r for r in rows if r["name"] == name]
    if not chosen:
        raise InputError(f"image {name} is not in the block; it has {', '.join(r['name'] for r in rows)}")
    return chosen


def cube_heights(blk: Block, h_min: float | None, h_max: float | None) -> tuple[float, float]:
    """(min, max) heights of the cube: both given (height_range.check_heights), or the Block
    `blk`'s terrain height range widened by a margin (rpc_fit.default_height_range)."""
    h_min, h_max = check_heights(
        h_min, h_max, "the lowest height of the RPC cube", "the highest height of the RPC cube"
    )
    if h_min is not None and h_max is not None:
        return h_min, h_max
    if h_min is not None or h_max is not None:
        raise InputError(
            "give both the lowest and the highest height of the RPC cube, or neither (then the "
            "block's terrain height range is used, widened by a margin)"
        )
    terrain = blk.height_range()
    if terrain is None:
        raise InputError(
            f"block {blk.path} records no terrain height range: give the lowest and highest heights of the RPC cube"
        )
    return rpc_fit.default_height_range(terrain)


def cube_warning(heights: tuple[float, float], terrain: tuple[float, float] | None) -> str | None:
    """The warning where the cube's `heights` (min, max) leave out some of the block's `terrain` height range
    (None: none recorded, or the cube holds it)."""
    if terrain is None or (heights[0] <= terrain[0] and heights[1] >= terrain[1]):
        return None
    return (
        f"the RPC cube's heights {heights[0]:g} .. {heights[1]:g} m leave out some of the block's terrain "
        f"({terrain[0]:.0f} .. {terrain[1]:.0f} m): the RPCs extrapolate there; leave MIN_HEIGHT and MAX_HEIGHT "
        "empty for the terrain's range and a margin"
    )


def rpc_height_check(blk: Block, rpcs: Mapping[int, RpcModel]) -> str:
    """The summary of surface.intersection.height_differences on the Block `blk`'s tie points, when
    it has tie points and RPCs were fitted for all their images ("" otherwise)."""
    if "tie_points" not in blk.info():
        return ""
    obs = blk.points("tie_points").observations
    images = set(np.unique(obs["image_id"]).tolist())
    if not images or not images <= set(rpcs):
        return ""
    rigorous = blk.models(sorted(images))
    return height_differences(
        rigorous,
        {i: rpcs[i] for i in images},
        obs["image_id"],
        obs["point_id"],
        obs["col"],
        obs["row"],
        h0=mean_height(blk.height_range()),
    ).summary()


def _destinations(rows: Sequence[dict[str, Any]], params: RpcParams) -> list[tuple[str, str | None]]:
    """(the _RPC.TXT path, the raster's own RPC or None) of each image row, checked writable, absent and, beside
    the rasters, not shadowing a raster's own RPC, unless overwriting (module docstring)."""
    destinations = []
    for row in rows:
        own = None
        if params.folder is None:
            if not row["image_path"]:
                raise InputError(f"image {row['name']} has no raster path in the block: give an output folder")
            own = rpc_fit.raster_rpc_source(row["image_path"])
        destination = rpc_fit.rpc_txt_path(row["image_path"], params.folder, row["name"])
        if own and own != destination and not params.overwrite:
            raise InputError(
                f"image {row['name']} carries its own RPC ({own}), which GDAL reads with "
                f"{row['image_path']}: a fitted {destination} beside it would replace it for every GDAL "
                "program and any block made from the image later. Give an output folder "
                "(OUTPUT_FOLDER), or set OVERWRITE to write beside the image all the same"
            )
        rpc_fit.check_destination(destination, params.overwrite)
        destinations.append((destination, None if own == destination else own))
    return destinations


def _gdal_reads(row: dict[str, Any], written: str, own: str | None, rpc: RpcModel, feedback: Feedback | None) -> None:
    """Warn which RPC GDAL reads with the image raster of `row` after `written` was put beside it: not the
    fitted one (a .RPB comes first), or the fitted one instead of the raster's `own`."""
    if not rpc_fit.raster_reads(row["image_path"], rpc):
        progress.warn(
            feedback,
            f"GDAL does not read {written} with {row['image_path']} (the raster carries other RPC "
            "metadata it prefers, or cannot be opened): load the _RPC.TXT itself",
        )
    elif own:
        progress.warn(
            feedback,
            f"GDAL now reads {written} with {row['image_path']} instead of the image's own RPC "
            f"({own}): every GDAL program, and any block made from the image, uses the fitted "
            f"RPC; delete {written} to return to the image's own",
        )


def fit_block_rpcs(block_path: str, params: RpcParams, feedback: Feedback | None = None) -> RpcResult:
    """Fit and write the RPCs of the block at `block_path` with RpcParams `params` (module docstring);
    returns an RpcResult. Raises InputError (an unknown image, no height range or an implausible one, a
    destination that exists or cannot be written, a raster's own RPC in the way without `overwrite`),
    rpc_fit's errors, CancelledError when cancelled."""
    params.check()
    blk = Block(block_path)
    rows = selected_images(blk.images(), params.image)
    heights = cube_heights(blk, params.min_height, params.max_height)
    progress.warn(feedback, cube_warning(heights, blk.height_range()))
    grid = (params.grid, params.grid, params.height_levels)
    destinations = _destinations(rows, params)
    fitted = []
    for k, row in enumerate(rows):
        progress.step(feedback, 95.0 * k / len(rows), f"fitting the RPC of {row['name']}")
        fitted.append(
            rpc_fit.fit_rpc(
                blk.model(row["id"]),
                heights,
                grid,
                feedback=progress.scaled(feedback, 95.0 * k / len(rows), 95.0 * (k + 1) / len(rows)),
            )
        )
    progress.step(feedback, 95.0)
    entries = []
    for row, (rpc, fit), (destination, own) in zip(rows, fitted, destinations):
        written = rpc_fit.write_fitted_rpc(rpc, destination, params.overwrite)
        entries.append((row["name"], written, fit))
        if params.folder is None:
            _gdal_reads(row, written, own, rpc, feedback)
    text = rpc_fit.report_text(entries)
    comparison = rpc_height_check(blk, {row["id"]: rpc for row, (rpc, _) in zip(rows, fitted)})
    if comparison:
        text += (
            "\n\nRPC minus rigorous object points of the block's tie points (Kornus et al. 2006, Table 5): "
            + comparison
        )
    progress.ensure(feedback).pushInfo(text)
    # storage: the step in the block's history
    blk.update_info({}, step="fitrpc", message="; ".join(f"{name}: {written}" for name, written, _ in entries))
    out = RpcResult([written for _, written, _ in entries])
    if params.report:
        out.report = report.write_html(params.report, f"RPC fit for {block_path}", text)
    return out
