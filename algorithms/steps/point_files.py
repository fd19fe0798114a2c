"""The point file steps (pushbroom:importpoints, pushbroom:exportpoints): control and check points
and their image measurements between a CSV file and the block (control_points.py has the format and
the checks). An import is one transaction: a bad file leaves the block as it was, and so does one that would
leave far fewer points, measured points or image measurements than the block holds (block/replacement.py),
unless `replace_fewer`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .. import progress
from ..adjustment import control_points as cp
from ..block import Block
from ..sigmas import IMAGE_SIGMA

if TYPE_CHECKING:
    from ..progress import Feedback


@dataclass
class ImportParams:
    """The import's settings; each is a pushbroom:importpoints parameter."""

    mode: str = "replace"  # one of Block.IMPORT_MODES
    crs: str | None = None  # CRS of x/y columns (authority id or WKT); None: WGS 84
    heights: str = "ellipsoidal"  # one of control_points.HEIGHT_TYPES
    default_role: str = "control"  # role of points without one (control_points.ROLES)
    check_ids: str = ""  # comma-separated ids made check points
    sigma_e: float = cp.DEFAULT_SIGMAS[0]  # m, default ground sigmas
    sigma_n: float = cp.DEFAULT_SIGMAS[1]
    sigma_h: float = cp.DEFAULT_SIGMAS[2]
    image_sigma: float = IMAGE_SIGMA  # px, default sigma of the image measurements
    suffix: str = ""  # measurement column suffix ('_meas' for the simulator's points.csv)
    keep_implausible: bool = False  # keep points that do not lie where the images are
    replace_fewer: bool = False  # replace the block's points even by far fewer (block/replacement.py)


@dataclass
class ImportResult:
    """The points in the block after an import."""

    control: int
    check: int
    measurements: int
    layer: str  # OGR source of the block's control point layer


def import_points(
    block_path: str, csv_path: str, params: ImportParams, feedback: Feedback | None = None
) -> ImportResult:
    """Import the CSV file `csv_path` into the block at `block_path` with ImportParams `params`; returns
    an ImportResult. Raises StorageError where the block cannot be written, and control_points.import_csv's
    InputErrors (format, CRS, implausible points, far fewer points or measurements than the block holds)."""
    # storage: control_points.import_csv writes the points and measurements in one transaction
    blk = Block(block_path)
    blk.check_writable("the imported points")  # before the file is read and checked
    stored = cp.import_csv(
        blk,
        csv_path,
        mode=params.mode,
        feedback=feedback,
        crs=params.crs,
        heights=params.heights,
        default_role=params.default_role,
        check_ids=[c.strip() for c in (params.check_ids or "").split(",")],
        sigmas=(params.sigma_e, params.sigma_n, params.sigma_h),
        image_sigma=params.image_sigma,
        suffix=params.suffix,
        keep_implausible=params.keep_implausible,
        replace_fewer=params.replace_fewer,
    )
    progress.ensure(feedback).pushInfo("points in the block: " + cp.summary(stored, blk.image_ids()))
    roles = stored.points["role"]
    return ImportResult(
        int((roles == "control").sum()),
        int((roles == "check").sum()),
        len(stored.measurements),
        blk.layer_source(Block.CONTROL_LAYER),
    )


def export_points(block_path: str, csv_path: str, feedback: Feedback | None = None) -> str:
    """Write the block's control and check points to `csv_path` in the format import_points reads;
    returns `csv_path`. Raises InputError when the block has no points."""
    blk = Block(block_path)
    stored = cp.export_csv(blk, csv_path)
    progress.ensure(feedback).pushInfo(f"{csv_path}: " + cp.summary(stored, blk.image_ids()))
    return csv_path
