"""DSM to DTM and DHM (pushbroom:extractdtm) with CNES Bulldozer (Lallement et al. 2023: the drape-cloth filter,
`bulldozer-dtm`, installed without its dependencies on Debian's rasterio, scikit-image and numpy).

Bulldozer reads its whole DSM into memory. So Bulldozer runs on windows of TILE x TILE cells (the DSM's size along
an axis where it is smaller; the columns rounded down to a multiple of 16 that is not one of 128, DtmParams.window),
each cut out as a GeoTIFF in a work folder and given to Bulldozer as a DSM of its own, as a task on the chosen
execution; each window keeps its inner tile, and GDAL assembles the inner tiles. The window holds a margin around
its inner tile wherever the DSM goes on: at least twice the largest object (`max_object_size`) or MIN_MARGIN cells,
whichever is more, so that the cloth sees every object whose cells reach into the tile (docs/validation.md#extract-dtm
measures the tiles' agreement with one run over the whole DSM). Along an axis (axis_tiles) the inner tiles are the
window less two margins, those at the DSM's border the window less one (they need none outside), and the windows at
the border are shifted inwards, not cut: every window has the same size, so a worker's memory is the same on any DSM
larger than a window, and follows the tile, not the scene
(docs/validation.md#dem-steps-memory).

Bulldozer keeps module-level state (its logger singleton, its parameters) and is not safe to run in several
threads of one process, nor is it meant to run inside QGIS's: its tiles run on local worker processes where threads
were chosen (execution.run_tasks, thread_safe off), one Bulldozer worker each (the tiles are the parallelism), and on
Dask as they are. A tile without any height is not given to Bulldozer: it stays nodata. A window's DSM and Bulldozer's
rasters are removed once its inner tile is kept: the work folder's disk, too, follows the tile.

Outputs: the DTM (Bulldozer's: its fill of the voids the DSM encloses kept, the voids open to a tile's border
nodata), the DHM = DSM - DTM (nodata where the DSM has none), and a mask (Byte): 1 a cell the DSM had no height in
and Bulldozer filled, 2 a pit Bulldozer filled, 0 otherwise; each a tiled GeoTIFF with overviews (the mask's by
nearest neighbour), written together or not at all. Whether a void touches a window's border depends on the tiling:
a void wider than the margin at a window's edge may stay nodata in one tiling and be filled in another.

Failure modes: InputError (Bulldozer not installed, a DSM without a CRS, in degrees or in another unit than the
metre, no valid height anywhere), ExecutionError, CancelledError.

Reference: Lallement, D., Lassalle, P., Lebègue, L., Youssefi, D., Bergerot, N., Labat, E., Cambier, S., 2023.
Bulldozer, a free open source scalable software for DTM extraction. ISPRS Archives XLVIII-1/W2-2023, 2029-2036."""

from __future__ import annotations

import importlib.util
import math
import os
import shutil
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import progress
from ..atomic import work_dir
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..progress import Feedback
from ..quality.rasters import open_raster, raster_srs, read_grid
from ..surface.geotiff import (
    CODE_OPTIONS,
    OPTIONS,
    Frame,
    assemble_tiles,
    raster_outputs,
    write_code_raster,
    write_float_raster,
)
from ..task_runtime import check_cancel

#: cells per side of a tile
TILE = 4096
#: the margin's least width (cells)
MIN_MARGIN = 64
#: the mask's codes
INNER_NODATA, FILLED_PIT = 1, 2


@dataclass(frozen=True)
class DtmParams:
    """pushbroom:extractdtm's settings."""

    max_object_size: float = 16.0  # m: Bulldozer's largest object above the ground
    max_ground_slope: float = 20.0  # %: Bulldozer's steepest ground
    dsm_nodata: float | None = None  # a void value of the DSM its file does not flag
    tile: int = TILE
    execution: Execution = field(default_factory=Execution)
    cog: bool = False

    def check(self) -> DtmParams:
        if not self.max_object_size > 0 or not self.max_ground_slope > 0 or self.tile < 3 * MIN_MARGIN:
            raise InputError(
                f"the largest object and the ground slope must be positive and the tile at least {3 * MIN_MARGIN} cells"
            )
        self.execution.check()
        return self

    def window(self) -> tuple[int, int]:
        """(columns, rows) of Bulldozer's windows: `tile` rows, and `tile` columns rounded down to a multiple of 16
        that is not one of 128 (window_columns)."""
        return window_columns(self.tile), self.tile

    def check_margin(self, margin: int, size: tuple[int, int]) -> None:
        """InputError where, along an axis of the DSM (`size`: columns, rows) longer than a window, a margin of
        `margin` cells on each side leaves less than a margin of the window inside, with the tile that would do."""
        if all(n <= w or w - 2 * margin >= margin for n, w in zip(size, self.window())):
            return
        need = -(-3 * margin // 16) * 16  # the least tile whose windows' columns hold three margins
        need += 16 if need % 128 == 0 else 0
        raise InputError(
            f"a tile of {self.tile} cells is too small for objects of {self.max_object_size:g} m: its margin of "
            f"{margin} cells on each side (twice the largest object) leaves less than a margin inside its windows; "
            f"give a tile of at least {need} cells"
        )


def window_columns(tile: int) -> int:
    """The columns of Bulldozer's windows for tiles of `tile` cells: `tile` rounded down to a multiple of 16 that is
    not one of 128. Bulldozer's drape cloth runs 2 to 3 times slower on rows of a multiple of 128 cells (2048: 8.9 s
    against 3.6 s for 2032; cache aliasing of its strided views, by every sign: docs/validation.md#extract-dtm)."""
    columns = tile - tile % 16
    return columns - 16 if columns % 128 == 0 else columns


@dataclass(frozen=True)
class DtmOutputs:
    dtm: str
    dhm: str | None = None
    mask: str | None = None


@dataclass(frozen=True)
class _Job:
    dsm: str
    nodata: float | None
    margin: int
    window: tuple[int, int]
    size: tuple[int, int]
    max_object_size: float
    max_ground_slope: float
    work: str


def bulldozer_available() -> None:
    """InputError, saying how to install it, where Bulldozer cannot be imported."""
    if importlib.util.find_spec("bulldozer") is None:
        raise InputError(
            "CNES Bulldozer is not installed: pip install --no-deps bulldozer-dtm==1.2.0 into the Python that runs "
            "QGIS's plugins (its dependencies rasterio, scikit-image, scipy, PyYAML, tqdm, psutil and argcomplete "
            "from the system's packages: a pip rasterio brings a second GDAL)"
        )


def margin_cells(params: DtmParams, cell: float) -> int:
    """The tiles' margin (module docstring), in cells of `cell` m."""
    return max(MIN_MARGIN, int(math.ceil(2 * params.max_object_size / cell)))


def axis_tiles(size: int, window: int, margin: int) -> list[tuple[int, int]]:
    """The inner tiles [start, stop) along an axis of `size` cells for windows of `window` cells with `margin`
    (module docstring): one where the axis fits a window; else the first and the last window - margin cells at most
    (no margin outside the axis), those between window - 2 margin."""
    if size <= window:
        return [(0, size)]
    bounds, start = [], 0
    while size - start > window - margin:
        stop = start + (window - margin if start == 0 else window - 2 * margin)
        bounds.append((start, stop))
        start = stop
    return [*bounds, (start, size)]


def window_of(start: int, stop: int, margin: int, window: int, size: int) -> tuple[int, int]:
    """The window [w0, w1) of `window` cells (of `size` where smaller) along an axis of `size` cells around the inner
    tile [start, stop) and `margin` cells on each side: centred on the margin, shifted inwards at the border."""
    w0 = min(max(start - margin, 0), max(size - window, 0))
    return w0, min(w0 + window, size)


def dtm_tile(job: _Job, k: int, box: tuple[int, int, int, int]) -> dict[str, Any]:
    """Task: Bulldozer on the window of tile `k` (`box`, window_of along each axis) of the DSM; writes the inner
    cells' DTM, DHM and mask to the work folder; returns their paths."""
    from bulldozer.pipeline.bulldozer_pipeline import dsm_to_dtm

    c0, r0, c1, r1 = box
    (cols, rows), m, (n_cols, n_rows) = job.size, job.margin, job.window
    (w0, w1), (h0, h1) = window_of(c0, c1, m, n_cols, cols), window_of(r0, r1, m, n_rows, rows)
    source = open_raster(job.dsm, "DSM")
    wide = read_grid(source, job.nodata, (w0, h0, w1, h1))
    inner = (slice(r0 - h0, r1 - h0), slice(c0 - w0, c1 - w0))
    x0, dx, _, y0, _, dy = wide.geotransform
    gt = (x0 + (c0 - w0) * dx, dx, 0.0, y0 + (r0 - h0) * dy, 0.0, dy)
    dsm = wide.values[inner]
    if not np.isfinite(wide.values).any():  # nothing for Bulldozer: the tile stays nodata
        return _tile_outputs(job.work, k, np.full(dsm.shape, np.nan), dsm, np.zeros(dsm.shape, np.uint8), gt, source)
    folder = os.path.join(job.work, f"tile-{k:05d}")
    os.makedirs(folder, exist_ok=True)
    cut = write_float_raster(os.path.join(folder, "dsm.tif"), wide.values, wide.geotransform, wide.srs, overviews=False)
    check_cancel()
    dsm_to_dtm(
        dsm_path=cut,
        output_dir=os.path.join(folder, "out"),
        generate_dhm=False,
        max_object_size=job.max_object_size,
        max_ground_slope=job.max_ground_slope,
        nb_max_workers=1,
        developer_mode=False,
    )
    check_cancel()
    out = os.path.join(folder, "out")
    dtm = _read(os.path.join(out, "dtm.tif"))[inner]
    pits = os.path.join(out, "masks", "filled_pits.tif")
    if not os.path.exists(pits):
        raise RuntimeError(f"Bulldozer wrote no {pits}: this Bulldozer is not the 1.2.0 the step is made for")
    mask = np.zeros(dtm.shape, np.uint8)
    mask[np.nan_to_num(_read(pits)[inner]) > 0] = FILLED_PIT
    mask[~np.isfinite(dsm) & np.isfinite(dtm)] = INNER_NODATA
    shutil.rmtree(folder)  # the window's DSM and Bulldozer's rasters (module docstring)
    return _tile_outputs(job.work, k, dtm, dsm, mask, gt, source)


def _tile_outputs(
    work: str, k: int, dtm: np.ndarray, dsm: np.ndarray, mask: np.ndarray, gt: tuple, source: Any
) -> dict[str, Any]:
    """Tile k's DTM, DHM and mask written to the work folder; their paths, and whether it had a height."""
    srs = raster_srs(source)
    paths: dict[str, Any] = {
        "dtm": write_float_raster(os.path.join(work, f"dtm-{k:05d}.tif"), dtm, gt, srs, overviews=False),
        "dhm": write_float_raster(os.path.join(work, f"dhm-{k:05d}.tif"), dsm - dtm, gt, srs, overviews=False),
        "mask": write_code_raster(os.path.join(work, f"mask-{k:05d}.tif"), mask, gt, srs),
        "heights": bool(np.isfinite(dtm).any()),
    }
    return paths


def _read(path: str) -> np.ndarray:
    """Band 1 of one of Bulldozer's rasters, NaN for its nodata."""
    return read_grid(open_raster(path, "Bulldozer's output")).values


def extract_dtm(dsm: str, outputs: DtmOutputs, params: DtmParams, feedback: Feedback | None = None) -> dict[str, str]:
    """The DTM, DHM and mask of the DSM raster `dsm` (module docstring); returns {output: path} of those written."""
    params = params.check()
    bulldozer_available()
    source = open_raster(dsm, "DSM")
    srs = raster_srs(source)
    if srs.IsGeographic():
        raise InputError(
            f"the DSM {dsm} is in longitude/latitude: Bulldozer works in metres; warp it to a projected CRS (its UTM "
            "zone) first"
        )
    if abs(srs.GetLinearUnits() - 1.0) > 1e-9:
        raise InputError(
            f"the DSM {dsm} is in {srs.GetLinearUnitsName()}: Bulldozer takes metres; warp it to a CRS in metres first"
        )
    gt, size = source.GetGeoTransform(), (source.RasterXSize, source.RasterYSize)
    cell = abs(gt[1])
    margin = margin_cells(params, cell)
    params.check_margin(margin, size)  # a tile too small for the objects: said before any work
    with work_dir(outputs.dtm, "the DTM's tiles") as work:
        job = _Job(
            str(dsm),
            params.dsm_nodata,
            margin,
            params.window(),
            size,
            params.max_object_size,
            params.max_ground_slope,
            work,
        )
        boxes = [
            (c0, r0, c1, r1)
            for r0, r1 in axis_tiles(size[1], params.window()[1], margin)
            for c0, c1 in axis_tiles(size[0], params.window()[0], margin)
        ]
        done = run_tasks(
            dtm_tile,
            [(job, k, box) for k, box in enumerate(boxes)],
            params.execution,
            progress.scaled(feedback, 0, 85),
            "Bulldozer tiles",
            thread_safe=False,  # Bulldozer's module-level state; never inside QGIS's process
        )
        if not any(d["heights"] for d in done):
            raise InputError(
                f"the DSM {dsm} holds no valid height (all its cells are nodata): check it, or its DSM_NODATA"
            )
        frame = Frame(gt, size, srs)
        wanted = [
            (outputs.dtm, "dtm", "digital terrain model (m, Bulldozer)"),
            (outputs.dhm, "dhm", "height above the ground (m): DSM - DTM"),
            (outputs.mask, "mask", "Bulldozer's mask: 1 inner nodata filled, 2 pit filled"),
        ]
        with raster_outputs([path for path, _, _ in wanted], params.cog) as temps:
            for tmp, (_, key, description) in zip(temps, wanted):
                if tmp:
                    assemble_tiles(
                        [d[key] for d in done],
                        tmp,
                        frame,
                        options=CODE_OPTIONS if key == "mask" else OPTIONS,
                        description=description,
                        feedback=progress.scaled(feedback, 85, 100),
                        overviews="NEAREST" if key == "mask" else "AVERAGE",  # no average of codes
                    )
    return {key: path for path, key, _ in wanted if path}
