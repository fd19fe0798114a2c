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
heights (surface/local_spread.py): a second round of tasks, each part with the refined points of the parts
beside it, so a part's spread does not depend on the tiling. Every other point has the one a priori image
sigma given.

Points that cannot be intersected are left out and counted in the log, which also gives per point group the
count and the median sigmas (intersection.Summary; sigma_h before the surface term). Storage: the points are
read from the block (Block.point_parts) and the step is recorded in its block_info (Block.update_info)."""
import functools
import os
from dataclasses import dataclass, field

import numpy as np

from .. import progress
from ..atomic import save_array, work_dir
from ..block import Block
from ..block.points import load_arrays
from ..dense import precision
from ..errors import InputError
from ..execution import Execution, run_tasks
from ..geodesy import metres_per_degree
from ..height_range import mean_height
from ..sigmas import IMAGE_SIGMA
from ..surface import intersection, pointcloud
from ..surface.local_spread import local_metres, local_spread, reach_m

#: the block's point sets that can be intersected
KINDS = ("mass_points", "tie_points")


@dataclass
class IntersectParams:
    """The intersection step's settings; each is a pushbroom:intersectpoints parameter."""

    kind: str = "mass_points"       # one of KINDS
    crs: str = None                 # output CRS (authority id or WKT); None: the block's UTM zone
    sigma: float = IMAGE_SIGMA      # px: a priori sigma of the image coordinates
    max_iterations: int = 10        # per point
    execution: Execution = field(default_factory=lambda: Execution("threads", 1))  # where the parts run

    def check(self):
        """Raise InputError for settings no intersection can use."""
        if self.kind not in KINDS:
            raise InputError(f"the points must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.sigma <= 0 or self.max_iterations < 1:
            raise InputError("the image sigma must be positive and the iterations at least 1")
        self.execution.check()
        return self


@dataclass
class IntersectResult:
    """What intersect_block_points wrote."""

    path: str           # the point cloud
    format: str         # "las", "laz" or "gpkg" (pointcloud.write_point_cloud)
    count: int          # points written
    layer: str = None   # OGR source of the point layer (GeoPackage output)


def _intersect_part(job, part, out):
    """Task: intersect the points of the part file `part` (block/points.py) with `job` = (models, h0,
    sigma, max_iter, what) and write the converged ones (lon, lat, h and the cloud fields) to `out`.
    Returns a small summary: points, written, status counts, intersection.Summary, sums of lon, lat and h; and
    of its refined dense points (precision.refined_dense, marked in `out`.refined.npy): their count, bounding
    box (lon, lon, lat, lat) and the image id of their template (the reference image)."""
    models, h0, sigma, max_iter, what = job
    multi = load_arrays(part)
    obs = multi.observations
    if len(obs) == 0:
        return {"points": 0, "written": 0, "status": {}, "summary": intersection.Summary(), "lonlat": (0, 0, 0),
                "refined": 0}
    unknown = set(np.unique(obs["image_id"]).tolist()) - set(models)
    if unknown:
        raise InputError(f"the {what} refer to image ids {sorted(unknown)} which the block does not have: "
                         "run the matching step again")
    result = intersection.intersect(models, obs["image_id"], obs["point_id"], obs["col"], obs["row"],
                                    sigma=precision.image_sigmas(multi.points, obs, sigma), h0=h0, max_iter=max_iter)
    pos = np.searchsorted(multi.points["id"], result.point).clip(max=max(len(multi) - 1, 0))
    if len(multi) == 0 or np.any(multi.points["id"][pos] != result.point):
        raise InputError(f"the stored {what} have observations of unknown points: run the matching step again")
    group = multi.points["group"][pos]
    ok = result.ok
    fields = pointcloud.cloud_fields(result, group=group, rho=multi.points["rho_min"][pos])
    lon, lat, h = result.lon[ok], result.lat[ok], result.h[ok]
    pointcloud.save_part(out, lon, lat, h, fields)
    refined = precision.refined_dense(multi.points)[pos][ok]
    done = {"points": len(result), "written": int(ok.sum()), "status": result.status_counts(),
            "summary": intersection.Summary().add(result, group),
            "lonlat": (float(lon.sum()), float(lat.sum()), float(h.sum())), "refined": int(refined.sum())}
    if refined.any():
        save_array(out + ".refined.npy", refined, "the intersected parts")
        template = obs["image_id"][np.isin(obs["point_id"], result.point[ok][refined]) & np.isnan(obs["rho"])]
        done.update(box=(float(lon[refined].min()), float(lon[refined].max()), float(lat[refined].min()),
                         float(lat[refined].max())), reference=int(np.bincount(template).argmax()))
    return done


def _spread_part(job, k):
    """Task, round 2: part k's refined dense points with the template's surface term in sigma_h
    (precision.with_spread of the local spread of the refined points of the parts whose boxes lie within
    `margin` degrees of part k's), written beside it; returns that file. `job`: (part files, their boxes or
    None, centre (lon, lat), R m, margin (dlon, dlat))."""
    files, boxes, centre, radius, margin = job
    lon, lat, h, fields = pointcloud.load_part(files[k])
    own = np.load(files[k] + ".refined.npy")
    box = boxes[k]
    near = [j for j, b in enumerate(boxes) if b is not None and b[0] <= box[1] + margin[0]
            and b[1] >= box[0] - margin[0] and b[2] <= box[3] + margin[1] and b[3] >= box[2] - margin[1]]
    context = [(p[0][m], p[1][m], p[2][m]) for p, m in
               ((pointcloud.load_part(files[j]), np.load(files[j] + ".refined.npy")) for j in near)]
    x, y = local_metres(np.concatenate([c[0] for c in context]), np.concatenate([c[1] for c in context]), centre)
    qx, qy = local_metres(lon[own], lat[own], centre)
    spread = local_spread(x, y, np.concatenate([c[2] for c in context]), qx, qy, radius)
    fields["sigma_h"][own] = precision.with_spread(fields["sigma_h"][own], spread).astype(np.float32)
    return pointcloud.save_part(files[k][:-len(".npz")] + "-spread.npz", lon, lat, h, fields)


def _with_spread(files, done, models, centre, mean_h, execution, feedback):
    """The part files, those with refined dense points replaced by round 2's (_spread_part); `centre` (lon,
    lat) and `mean_h` of the cloud."""
    refined = [k for k, d in enumerate(done) if d["refined"]]
    if not refined:
        return files
    reference = models[int(np.bincount([done[k]["reference"] for k in refined]).argmax())]
    col, row = reference.ground_to_image(np.array([centre[0]]), np.array([centre[1]]), np.array([mean_h]))
    radius = precision.spread_radius(reference, col[0], row[0], mean_h)
    east, north = metres_per_degree(centre[1])
    margin = 1.01 * reach_m(radius)         # and 1 % for the local frame's approximation of the ellipsoid
    job = (files, [d.get("box") for d in done], centre, radius, (margin / east, margin / north))
    spread = run_tasks(_spread_part, [(job, k) for k in refined], execution, feedback,
                       "the dense points' precision")
    out = list(files)
    for k, path in zip(refined, spread):
        out[k] = path
    return out


def intersect_block_points(block_path, output, params=None, feedback=None):
    """Intersect the block's points (IntersectParams `params`) and write them to the point cloud `output`;
    returns an IntersectResult. Raises InputError (no points or measurements, unknown images or points,
    none intersected), ExecutionError (module execution's), CancelledError when cancelled."""
    params = (params or IntersectParams()).check()
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
    job = (models, None if heights is None else mean_height(heights), params.sigma, params.max_iterations, what)
    with work_dir(output, "the intersected parts") as work:
        files = [os.path.join(work, f"part-{k:05d}.npz") for k in range(len(parts))]
        done = run_tasks(_intersect_part, [(job, part, out) for part, out in zip(parts, files)], params.execution,
                         progress.scaled(feedback, 0, 70), "the intersection")
        points = sum(d["points"] for d in done)
        if points == 0 or all(not d["status"] for d in done):
            raise InputError(f"the block's {what} have no image measurements")
        status, summary = {}, intersection.Summary()
        for d in done:
            summary.merge(d["summary"])
            for name, n in d["status"].items():
                status[name] = status.get(name, 0) + n
        written = sum(d["written"] for d in done)
        log.pushInfo(f"{points} {what} in {len(parts)} part(s): "
                     + ", ".join(f"{name} {n}" for name, n in status.items()))
        log.pushInfo("per point group (a priori sigmas in m from the image sigma; sigma0 a posteriori):\n"
                     + intersection.format_summary(summary.rows()))
        if written == 0:
            raise InputError(f"none of the {points} points could be intersected ({status}): check the block's sensor "
                             "models and the points")
        centre, mean_h = (tuple(sum(d["lonlat"][i] for d in done) / written for i in range(2)),
                          sum(d["lonlat"][2] for d in done) / written)
        files = _with_spread(files, done, models, centre, mean_h, params.execution,
                             progress.scaled(feedback, 70, 80))
        kept = [f for f, d in zip(files, done) if d["written"]]
        out, srs, fmt = pointcloud.write_point_cloud_parts(
            output, [functools.partial(pointcloud.load_part, f) for f in kept], written, centre=centre,
            crs=params.crs or blk.info().get("default_crs"), feedback=progress.scaled(feedback, 80, 100))
    message = f"{written} points written to {out} ({srs.GetName()}; z ellipsoidal height)"
    log.pushInfo(message)
    # storage: the step in the block's info
    blk.update_info({}, step="intersectpoints", message=message)
    layer = f"{out}|layername={pointcloud.GPKG_LAYER}" if fmt == "gpkg" else None
    return IntersectResult(out, fmt, written, layer)
