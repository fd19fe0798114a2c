"""The intersection step's second round (block_intersection.py): what a point of the cloud needs from the points
around it, part by part, each part with the points of the parts beside it.

- The refined dense points' template-surface term in sigma_h (dense/precision.py): the local spread of the
  refined points' heights (surface/local_spread.py), half-width R at the reference image's pixel size.
- With `neighbours` k > 0, the statistical outlier removal (surface/outlier_filter.py): each point's mean
  distance to its k nearest points, the cloud's threshold mu + n s from the parts' sums, and the points above it
  left out of the cloud.

Round 1 leaves per part its point file (pointcloud.save_part), `.refined.npy` where it has refined dense points,
and its bounding box. A part's context is the points of every part whose box lies within the margin of its own
(the larger of the spread's reach and the outlier filter's margin), cut to that margin: the results do not
depend on the execution, and memory follows a part and its neighbours. Each task writes the part again with the
new sigma_h, and its distances to `.distance.npy`."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ..atomic import save_array
from ..dense import precision
from ..execution import run_tasks
from ..geodesy import metres_per_degree
from ..surface import outlier_filter, pointcloud
from ..surface.local_spread import local_metres, local_spread, reach_m

if TYPE_CHECKING:
    from ..execution import Execution
    from ..progress import Feedback
    from ..sensors.base import SensorModel

#: a part of the cloud as pointcloud.load_part gives it: (lon, lat, h, fields)
Part = tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]


class FirstRound(NamedTuple):
    """What round 1 (block_intersection.py) left: per part its point file and its summary (box, refined,
    reference, written), and the cloud's mean position."""

    files: list[str]  # the parts' point files
    done: list[dict[str, Any]]  # the parts' summaries, in the order of `files`
    centre: tuple[float, float]  # (lon, lat) of the cloud: the local frame
    mean_h: float  # m: the cloud's mean ellipsoidal height


class OutlierRemoval(NamedTuple):
    """The statistical outlier removal's settings (surface/outlier_filter.py)."""

    neighbours: int  # k, the nearest points a point's mean distance is taken to (0: off)
    factor: float  # n: a point whose mean distance d > mu + n s is an outlier


@dataclass
class Neighbourhood:
    """What every task of the round shares."""

    files: list[str]  # the parts' point files (round 1)
    boxes: list  # per part (lon0, lon1, lat0, lat1) of its points, or None (no point)
    centre: tuple[float, float]  # (lon, lat) of the cloud: the local frame
    radius: float  # m: R of the spread (0: no refined dense point)
    spread_factor: float  # C of the spread term (precision.Calibration.spread of the block's sensors)
    margin: tuple[float, float]  # (dlon, dlat) degrees around a part's box
    neighbours: int  # k of the outlier filter (0: off)


def _refined(path: str, count: int) -> np.ndarray:
    name = path + ".refined.npy"
    return np.load(name) if os.path.exists(name) else np.zeros(count, bool)


def _part(job: Neighbourhood, k: int) -> tuple[str, tuple[int, float, float]]:
    """Task: part k with its refined points' sigma_h and (with the filter) its points' mean distances; returns
    (its new file, (count, sum, sum of squares) of its finite distances)."""
    lon, lat, h, fields = pointcloud.load_part(job.files[k])
    own = _refined(job.files[k], lon.size)
    lo0, lo1, la0, la1 = job.boxes[k]
    dlon, dlat = job.margin
    ctx = []
    for j, b in enumerate(job.boxes):
        if b is None or b[0] > lo1 + dlon or b[1] < lo0 - dlon or b[2] > la1 + dlat or b[3] < la0 - dlat:
            continue
        c = pointcloud.load_part(job.files[j])
        inside = (c[0] >= lo0 - dlon) & (c[0] <= lo1 + dlon) & (c[1] >= la0 - dlat) & (c[1] <= la1 + dlat)
        ctx.append((c[0][inside], c[1][inside], c[2][inside], _refined(job.files[j], c[0].size)[inside]))
    clon, clat, ch, cref = (np.concatenate([c[i] for c in ctx]) for i in range(4))
    cx, cy = local_metres(clon, clat, job.centre)
    x, y = local_metres(lon, lat, job.centre)
    if own.any():
        spread = local_spread(cx[cref], cy[cref], ch[cref], x[own], y[own], job.radius)
        fields["sigma_h"][own] = precision.with_spread(fields["sigma_h"][own], spread, job.spread_factor).astype(
            np.float32
        )
    sums = (0, 0.0, 0.0)
    if job.neighbours:
        d = outlier_filter.mean_distances(np.c_[cx, cy, ch], np.c_[x, y, h], job.neighbours)
        save_array(job.files[k] + ".distance.npy", d, "the intersected parts")
        f = d[np.isfinite(d)]
        sums = (int(f.size), float(f.sum()), float(np.square(f).sum()))
    out = pointcloud.save_part(job.files[k][: -len(".npz")] + "-2.npz", lon, lat, h, fields)
    return out, sums


def load_kept(path: str, distances: str, limit: float) -> Part:
    """(lon, lat, h, fields) of the part file `path` without the points whose distance (`distances` .npy)
    exceeds `limit` (NaN distances are kept)."""
    lon, lat, h, fields = pointcloud.load_part(path)
    keep = ~(np.load(distances) > limit)
    return lon[keep], lat[keep], h[keep], {name: v[keep] for name, v in fields.items()}


def second_round(
    first: FirstRound,
    models: dict[int, SensorModel],
    outliers: OutlierRemoval,
    execution: Execution,
    feedback: Feedback | None,
    log: Feedback,
) -> tuple[list[Callable[[], Part]], int]:
    """Run the round (module docstring) over the parts round 1 left (`first`), `models` the block's, with the
    outlier removal `outliers` (neighbours 0: off), the tasks on `execution` with progress to `feedback` and the
    filter's line to `log`; returns (per part a function giving its points, as pointcloud.write_point_cloud_parts
    takes them; the points kept). Without refined dense points or the filter, the parts as they are."""
    files, done, centre, mean_h = first
    neighbours, factor = outliers
    loaders: list[Callable[[], Part]] = [functools.partial(pointcloud.load_part, f) for f in files]
    written = sum(d["written"] for d in done)
    refined = [d for d in done if d["refined"]]
    if not refined and not neighbours:
        return loaders, written
    east, north = metres_per_degree(centre[1])
    radius = reach = 0.0
    if refined:
        reference = models[int(np.bincount([d["reference"] for d in refined]).argmax())]
        col, row = reference.ground_to_image(np.array([centre[0]]), np.array([centre[1]]), np.array([mean_h]))
        # arrays in, arrays out: np.asarray only tells the type checker so (it returns the same arrays)
        radius = precision.spread_radius(reference, np.asarray(col)[0], np.asarray(row)[0], mean_h)
        reach = reach_m(radius)
    if neighbours:
        boxes = [d["box"] for d in done if d["written"]]
        area = sum(max((b[1] - b[0]) * east * (b[3] - b[2]) * north, 1.0) for b in boxes)
        reach = max(reach, outlier_filter.margin(written, area, neighbours))
    margin = 1.01 * reach  # and 1 % for the local frame's approximation of the ellipsoid
    job = Neighbourhood(
        files,
        [d.get("box") for d in done],
        centre,
        radius,
        precision.calibration_of(models.values()).spread,
        (margin / east, margin / north),
        int(neighbours),
    )
    todo = [k for k, d in enumerate(done) if d["written"] and (d["refined"] or neighbours)]
    results = run_tasks(_part, [(job, k) for k in todo], execution, feedback, "the points' neighbourhoods")
    for k, (path, _) in zip(todo, results):
        loaders[k] = functools.partial(pointcloud.load_part, path)
    if not neighbours:
        return loaders, written
    count, total, squares = (sum(s[i] for _, s in results) for i in range(3))
    if count == 0:
        return loaders, written
    limit = outlier_filter.threshold(count, total, squares, factor)
    kept = 0
    for k, (path, _) in zip(todo, results):
        distances = files[k] + ".distance.npy"
        kept += int((~(np.load(distances) > limit)).sum())
        loaders[k] = functools.partial(load_kept, path, distances, limit)
    log.pushInfo(
        f"statistical outlier removal (k {neighbours}, n {factor:g}): mean distance to the neighbours "
        f"{total / count:.3f} m, threshold {limit:.3f} m; {written - kept} of {written} points removed "
        f"({100.0 * (written - kept) / written:.2f} %)"
    )
    return loaders, kept
