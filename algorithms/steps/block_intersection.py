"""The intersection step (pushbroom:intersectpoints): object points of a block's mass or tie points by
forward intersection with the block's current sensor models (intersection.intersect; Kornus et al.
2006, section 3.5.1), written as a point cloud (pointcloud.write_point_cloud_parts: LAS/LAZ, or a
GeoPackage point layer) in the output CRS, default the block's UTM zone, z = WGS 84 ellipsoidal height.

Tiled: each part of the stored points (block/points.py) is one task on the chosen execution
(execution.run_tasks), which intersects it and writes its object points to a file in a work folder
beside the output; the cloud is then written part by part. Memory follows the part and the number of
workers, not the scene, and the cloud does not depend on the execution (parts keep their order).

Precision: the refined dense points are intersected with image sigmas from LSM's error ellipses, and their
sigma_h takes the template's surface term (dense/precision.py), from the local spread of the refined points'
heights. Every other point has the one a priori image sigma given. Optionally (outlier_neighbours k > 0) the
statistical outlier removal leaves out the points whose mean distance to their k nearest points is beyond the
cloud's mu + n s (surface/outlier_filter.py). Both are a second round of tasks, each part with the points of
the parts beside it (cloud_neighbourhood.py).

Colour (`colour`, on by default): each point's red, green and blue from the first image of the block that observes
it (surface/point_colour.py: grey for a one-band image, each band stretched to 16 bits once per image), in the LAS
colour fields (point format 7) or the GeoPackage's red, green and blue fields.

With an EPT folder (`ept`, LAS/LAZ output only), the cloud is also indexed as Entwine Point Tiles from the written
file (surface/ept.py): what QGIS without its PDAL provider (Debian 12's) opens as a point cloud.

Points that cannot be intersected are left out and counted in the log, which also gives per point group the
count and the median sigmas (intersection.Summary; sigma_h before the surface term). Storage: the points are
read from the block (Block.point_parts) and the step is recorded in its block_info (Block.update_info)."""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from .. import progress
from ..atomic import atomic_path, save_array, work_dir
from ..block import Block
from ..block.points import load_arrays
from ..dense import precision
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..height_range import mean_height
from ..sensors.base import SensorModel
from ..sigmas import IMAGE_SIGMA
from ..surface import ept, intersection, outlier_filter, point_colour, pointcloud
from ..task_runtime import check_cancel
from .cloud_neighbourhood import FirstRound, OutlierRemoval, second_round

if TYPE_CHECKING:
    from ..progress import Feedback

#: the most neighbours the outlier removal takes
MAX_NEIGHBOURS = 100
#: the block's point sets that can be intersected
KINDS = ("mass_points", "tie_points")


@dataclass
class IntersectParams:
    """The intersection step's settings; each is a pushbroom:intersectpoints parameter."""

    kind: str = "mass_points"  # one of KINDS
    crs: str | None = None  # output CRS (authority id or WKT); None: the block's UTM zone
    sigma: float = IMAGE_SIGMA  # px: a priori sigma of the image coordinates
    max_iterations: int = 10  # per point
    outlier_neighbours: int = 0  # k of the statistical outlier removal (surface/outlier_filter.py); 0: off
    outlier_factor: float = outlier_filter.FACTOR  # its n: d > mu + n s is an outlier
    colour: bool = True  # the points' colours from the block's images (point_colour.py)
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # where the parts run

    def check(self) -> IntersectParams:
        """Raise InputError for settings no intersection can use."""
        if self.kind not in KINDS:
            raise InputError(f"the points must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.sigma <= 0 or self.max_iterations < 1:
            raise InputError("the image sigma must be positive and the iterations at least 1")
        if not (0 <= self.outlier_neighbours <= MAX_NEIGHBOURS and self.outlier_factor > 0):
            raise InputError(
                f"the outlier removal needs 0 (off) to {MAX_NEIGHBOURS} neighbours and a positive factor, "
                f"got {self.outlier_neighbours} and {self.outlier_factor}"
            )
        self.execution.check()
        return self


@dataclass
class IntersectResult:
    """What intersect_block_points wrote."""

    path: str  # the point cloud
    format: str  # "las", "laz" or "gpkg" (pointcloud.write_point_cloud)
    count: int  # points written
    layer: str | None = None  # OGR source of the point layer (GeoPackage output)
    ept: str | None = None  # the EPT index's ept.json, where asked


class _Job(NamedTuple):
    """What every task of the first round shares."""

    models: dict[int, SensorModel]
    h0: float | None  # m: the intersection's start height
    sigma: float  # px: the a priori image sigma
    max_iter: int
    what: str  # the points, as messages name them
    colour: dict[int, point_colour.BandStretch] | None  # {image id: its stretch}, in block order; None: no colours


def _intersect_part(job: _Job, part: str, out: str) -> dict[str, Any]:
    """Task: intersect the points of the part file `part` (block/points.py) with the _Job `job` and write the
    converged ones (lon, lat, h and the cloud fields, their colours where the job has them) to `out`.
    Returns a small summary: points, written, status counts, intersection.Summary, sums of lon, lat and h; and
    the bounding box (lon, lon, lat, lat) of its points; the count of its refined dense points
    (precision.refined_dense, marked in `out`.refined.npy) and the image id of their template (the reference
    image)."""
    models, h0, sigma, max_iter, what, stretch = job
    calibration = precision.calibration_of(models.values())
    multi = load_arrays(part)
    obs = multi.observations
    if len(obs) == 0:
        return {
            "points": 0,
            "written": 0,
            "status": {},
            "summary": intersection.Summary(),
            "lonlat": (0, 0, 0),
            "refined": 0,
        }
    unknown = set(np.unique(obs["image_id"]).tolist()) - set(models)
    if unknown:
        raise InputError(
            f"the {what} refer to image ids {sorted(unknown)} which the block does not have: "
            "run the matching step again"
        )
    result = intersection.intersect(
        models,
        intersection.Measurements(
            obs["image_id"],
            obs["point_id"],
            obs["col"],
            obs["row"],
            precision.image_sigmas(multi.points, obs, sigma, calibration.factors),
        ),
        h0=h0,
        max_iter=max_iter,
    )
    pos = np.searchsorted(multi.points["id"], result.point).clip(max=max(len(multi) - 1, 0))
    if len(multi) == 0 or np.any(multi.points["id"][pos] != result.point):
        raise InputError(f"the stored {what} have observations of unknown points: run the matching step again")
    group = multi.points["group"][pos]
    ok = result.ok
    fields = pointcloud.cloud_fields(result, group=group, rho=multi.points["rho_min"][pos])
    colour_error = None
    if stretch is not None:
        try:
            rgb = point_colour.colours(
                stretch, result.point[ok], obs["image_id"], obs["point_id"], obs["col"], obs["row"]
            )
        except (InputError, RuntimeError) as exc:  # an image unreadable here: this part uncoloured, and said
            colour_error = str(exc)
            rgb = np.zeros((int(ok.sum()), 3), np.uint16)
        fields.update(zip(pointcloud.COLOUR_FIELDS, rgb.T))
    lon, lat, h = result.lon[ok], result.lat[ok], result.h[ok]
    check_cancel()  # before the write (execution: a cancel reaches a running part)
    pointcloud.save_part(out, lon, lat, h, fields)
    refined = precision.refined_dense(multi.points)[pos][ok]
    done: dict[str, Any] = {
        "points": len(result),
        "written": int(ok.sum()),
        "status": result.status_counts(),
        "summary": intersection.Summary().add(result, group),
        "lonlat": (float(lon.sum()), float(lat.sum()), float(h.sum())),
        "refined": int(refined.sum()),
        "colour_error": colour_error,
    }
    if ok.any():
        done["box"] = (float(lon.min()), float(lon.max()), float(lat.min()), float(lat.max()))
    if refined.any():
        save_array(out + ".refined.npy", refined, "the intersected parts")
        template = obs["image_id"][np.isin(obs["point_id"], result.point[ok][refined]) & np.isnan(obs["rho"])]
        done["reference"] = int(np.bincount(template).argmax())
    return done


def intersect_block_points(
    block_path: str,
    output: str,
    params: IntersectParams | None = None,
    feedback: Feedback | None = None,
    ept_folder: str | None = None,
) -> IntersectResult:
    """Intersect the block's points (IntersectParams `params`) and write them to the point cloud `output`, and its
    EPT index to `ept_folder` where given; returns an IntersectResult. Raises InputError (no points or measurements,
    unknown images or points, none intersected, an EPT of a GeoPackage), ExecutionError (module execution's),
    CancelledError when cancelled."""
    params = (params or IntersectParams()).check()
    if ept_folder and pointcloud.output_format(output, 0) == "gpkg":
        raise InputError("an EPT index is made from a LAS or LAZ point cloud: name the output .las or .laz")
    log = progress.ensure(feedback)
    kind, what = params.kind, params.kind.replace("_", " ")
    # storage: the point parts, the images and their models
    blk = Block(block_path)
    parts = blk.point_parts(kind)
    images = [r["id"] for r in blk.images()]
    if not images:
        raise InputError("the block has no images")
    models = blk.models(images)
    heights = blk.height_range()
    stretch = None
    if params.colour:
        progress.step(feedback, 0, "the images' colour stretch")
        try:
            stretch = point_colour.stretches({r["id"]: r["image_path"] for r in blk.images() if r["image_path"]})
        except (InputError, RuntimeError) as exc:
            progress.warn(feedback, f"the points are written without colours: {exc}")
    job = _Job(
        models,
        None if heights is None else mean_height(heights),
        params.sigma,
        params.max_iterations,
        what,
        stretch,
    )
    with work_dir(output, "the intersected parts") as work:
        files = [os.path.join(work, f"part-{k:05d}.npz") for k in range(len(parts))]
        done = run_tasks(
            _intersect_part,
            [(job, part, out) for part, out in zip(parts, files)],
            params.execution,
            progress.scaled(feedback, 0, 70),
            "the intersection",
        )
        points = sum(d["points"] for d in done)
        failed = [d["colour_error"] for d in done if d.get("colour_error")]
        if failed:
            progress.warn(feedback, f"{len(failed)} part(s) of the cloud are written without colours: {failed[0]}")
        if points == 0 or all(not d["status"] for d in done):
            raise InputError(f"the block's {what} have no image measurements")
        status: dict[str, int] = {}
        summary = intersection.Summary()
        for d in done:
            summary.merge(d["summary"])
            for name, n in d["status"].items():
                status[name] = status.get(name, 0) + n
        written = sum(d["written"] for d in done)
        log.pushInfo(
            f"{points} {what} in {len(parts)} part(s): " + ", ".join(f"{name} {n}" for name, n in status.items())
        )
        log.pushInfo(
            "per point group (a priori sigmas in m from the image sigma; sigma0 a posteriori):\n"
            + intersection.format_summary(summary.rows())
        )
        if written == 0:
            raise InputError(
                f"none of the {points} points could be intersected ({status}): check the block's sensor "
                "models and the points"
            )
        centre, mean_h = (
            tuple(sum(d["lonlat"][i] for d in done) / written for i in range(2)),
            sum(d["lonlat"][2] for d in done) / written,
        )
        loaders, written = second_round(
            FirstRound(files, done, centre, mean_h),
            models,
            OutlierRemoval(params.outlier_neighbours, params.outlier_factor),
            params.execution,
            progress.scaled(feedback, 70, 80),
            log,
        )
        index = None
        with atomic_path(output) if ept_folder else contextlib.nullcontext(output) as target:
            # with an EPT, the cloud is renamed only once its index is written: both, or neither
            _, srs, fmt = pointcloud.write_point_cloud_parts(
                target,
                [load for load, d in zip(loaders, done) if d["written"]],
                written,
                centre=centre,
                crs=params.crs or blk.info().get("default_crs"),
                feedback=progress.scaled(feedback, 80, 100 if not ept_folder else 90),
            )
            if ept_folder:
                made = ept.write_ept(target, ept_folder, progress.scaled(feedback, 90, 100))
                index = os.path.join(made.folder, "ept.json")
    out = os.fspath(output)
    message = f"{written} points written to {out} ({srs.GetName()}; z ellipsoidal height)"
    log.pushInfo(message)
    if index:
        log.pushInfo(f"EPT index of {made.points} points in {made.nodes} nodes (depth {made.depth}): {index}")
    # storage: the step in the block's info
    blk.update_info({}, step="intersectpoints", message=message)
    layer = f"{out}|layername={pointcloud.GPKG_LAYER}" if fmt == "gpkg" else None
    return IntersectResult(out, fmt, written, layer, index)
