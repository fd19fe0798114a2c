"""The intersection step (pushbroom:intersectpoints): object points of a block's mass or tie points by
forward intersection with the block's current sensor models (intersection.intersect; Kornus et al.
2006, section 3.5.1), written as a point cloud (pointcloud.write_point_cloud: LAS/LAZ, or a GeoPackage
point layer) in the output CRS, default the block's UTM zone, z = WGS 84 ellipsoidal height.

Points that cannot be intersected are left out and counted in the log, which also gives per point
group the count and the median sigmas. Storage: the points are read from the block
(Block.points) and the step is recorded in its block_info (Block.update_info)."""
from dataclasses import dataclass

import numpy as np

from .. import progress
from ..block import Block
from ..errors import InputError
from ..height_range import mean_height
from ..sigmas import IMAGE_SIGMA
from ..surface import intersection, pointcloud

#: the block's point sets that can be intersected
KINDS = ("mass_points", "tie_points")


@dataclass
class IntersectParams:
    """The intersection step's settings; each is a pushbroom:intersectpoints parameter."""

    kind: str = "mass_points"       # one of KINDS
    crs: str = None                 # output CRS (authority id or WKT); None: the block's UTM zone
    sigma: float = IMAGE_SIGMA      # px: a priori sigma of the image coordinates
    max_iterations: int = 10        # per point

    def check(self):
        """Raise InputError for settings no intersection can use."""
        if self.kind not in KINDS:
            raise InputError(f"the points must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.sigma <= 0 or self.max_iterations < 1:
            raise InputError("the image sigma must be positive and the iterations at least 1")
        return self


@dataclass
class IntersectResult:
    """What intersect_block_points wrote."""

    path: str           # the point cloud
    format: str         # "las", "laz" or "gpkg" (pointcloud.write_point_cloud)
    count: int          # points written
    layer: str = None   # OGR source of the point layer (GeoPackage output)


def _check_images(multi, kind, known):
    """The image ids of `multi`'s observations, all of them in the block (`known`)."""
    what = kind.replace("_", " ")
    ids = [int(i) for i in multi.image_ids()]
    if not ids:
        raise InputError(f"the block's {what} have no image measurements")
    if set(ids) - known:
        raise InputError(f"the {what} refer to image ids {sorted(set(ids) - known)} which the block does not have: "
                         "run the matching step again")
    return ids


def intersect_block_points(block_path, output, params=None, feedback=None):
    """Intersect the block's points (IntersectParams `params`) and write them to the point cloud `output`;
    returns an IntersectResult. Raises InputError (no points or measurements, unknown images or points,
    none intersected), CancelledError when cancelled."""
    params = (params or IntersectParams()).check()
    log = progress.ensure(feedback)
    kind, what = params.kind, params.kind.replace("_", " ")
    # storage: the points, the images and their models
    blk = Block(block_path)
    multi = blk.points(kind)
    ids = _check_images(multi, kind, {r["id"] for r in blk.images()})
    models = blk.models(ids)
    heights = blk.height_range()
    obs = multi.observations
    result = intersection.intersect(models, obs["image_id"], obs["point_id"], obs["col"], obs["row"],
                                    sigma=params.sigma, h0=None if heights is None else mean_height(heights),
                                    max_iter=params.max_iterations, feedback=progress.scaled(feedback, 0, 80))
    pos = np.searchsorted(multi.points["id"], result.point).clip(max=max(len(multi) - 1, 0))
    if len(multi) == 0 or np.any(multi.points["id"][pos] != result.point):
        raise InputError(f"the stored {what} have observations of unknown points: run the matching step again")
    group = multi.points["group"][pos]
    log.pushInfo(f"{len(result)} {what}: " + ", ".join(f"{name} {n}" for name, n in result.status_counts().items()))
    log.pushInfo("per point group (a priori sigmas in m from the image sigma; sigma0 a posteriori):\n"
                 + intersection.format_summary(intersection.summary_rows(result, group)))
    ok = result.ok
    if not ok.any():
        raise InputError(f"none of the {len(result)} points could be intersected "
                         f"({result.status_counts()}): check the block's sensor models and the points")
    crs = params.crs or blk.info().get("default_crs")
    fields = pointcloud.cloud_fields(result, group=group, rho=multi.points["rho_min"][pos])
    out, srs, fmt = pointcloud.write_point_cloud(output, result.lon[ok], result.lat[ok], result.h[ok], fields,
                                                 crs=crs, feedback=progress.scaled(feedback, 80, 100))
    message = f"{int(ok.sum())} points written to {out} ({srs.GetName()}; z ellipsoidal height)"
    log.pushInfo(message)
    # storage: the step in the block's info
    blk.update_info({}, step="intersectpoints", message=message)
    layer = f"{out}|layername={pointcloud.GPKG_LAYER}" if fmt == "gpkg" else None
    return IntersectResult(out, fmt, int(ok.sum()), layer)
