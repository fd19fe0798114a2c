"""Transfer of a point clicked in one image into the block's other images by least-squares matching
(Heipke et al. 1992, section 2; Kornus et al. 2006, section 3.3), for the measurement window.

Initial values come from the sensor models: with a `height` (m, e.g. the point's own or the DEM's
at it) the clicked ray at that height is projected into the target and the normalised
cross-correlation is searched within `radius` px of that prediction (orientation errors of the
supplied models reach a few pixels), else the path that the ray over a height range (h_min, h_max)
traces in the target is searched (seeds.seeds_from_points). The best correlation peak, if it is
distinct (NCC >= 0.7, 0.05 above any rival more than 2 px away), is refined by LSM on the
resolution-adapted images (resolution.adapt_resolution: the finer image low-passed to the
coarser one's footprint, HRG vs HRS) and accepted with the papers' criteria (params.LsmParams:
rho > rho_min, error-ellipse semi-major axis < max_ellipse, shift < max_shift, converged).

Only windows around the point are read (matching/imagery.py: GDAL windowed reads), never a whole
image."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, NamedTuple, cast

import numpy as np

from ..errors import InputError
from ..height_range import HeightRange
from ..matching.imagery import as_image
from ..matching.pair_geometry import ImagePair, predict
from ..matching.params import GrowParams
from ..matching.resolution import adapt_resolution
from ..matching.seeds import NCC_MARGIN, NCC_MIN, seeds_from_points

#: px of the target searched around the prediction when a height is given
DEFAULT_RADIUS = 10.0


class Click(NamedTuple):
    """A position (col, row: px, GDAL convention) clicked in the image `image_id`."""

    image_id: Any
    col: float
    row: float


@dataclass(frozen=True)
class Transfer:
    """The match in one target image: position (px, NaN without a match), correlation rho, sigma_px
    (semi-major axis of the 1-sigma error ellipse, px of the target), ok (accepted by the criteria)
    and reason (why not, "" when ok)."""

    col: float
    row: float
    rho: float
    sigma_px: float
    ok: bool
    reason: str


def _reason(rec, params):
    """Why the match `rec` (PAIR_DTYPE) fails the acceptance criteria."""
    if not (np.isfinite(rec["x2"]) and np.isfinite(rec["rho"])):
        return (
            f"no distinct correlation peak near the prediction (NCC below {NCC_MIN}, or a rival peak within "
            f"{NCC_MARGIN}: too little or repetitive texture), or the template reaches beyond an image border"
        )
    if not rec["rho"] > params.rho_min:
        return f"correlation rho {rec['rho']:.2f} is not above {params.rho_min}"
    if not rec["semi_major"] < params.max_ellipse:
        return f"error ellipse {rec['semi_major']:.3f} px is not below {params.max_ellipse} px"
    if not rec["shift"] < params.max_shift:
        return f"LSM moved {rec['shift']:.1f} px from the correlation peak (limit {params.max_shift} px)"
    if rec["iterations"] >= params.max_iterations:
        return f"least-squares matching did not converge in {params.max_iterations} iterations"
    return "least-squares matching failed (singular normal equations)"


def _failed(reason):
    return Transfer(math.nan, math.nan, math.nan, math.nan, False, reason)


def transfer(
    images: dict[Any, Any],
    models: dict[Any, Any],
    click: Click,
    targets: Iterable[Any] | None = None,
    height: float | tuple[float, float] | None = None,
    params: GrowParams | None = None,
    radius: float = DEFAULT_RADIUS,
) -> dict[Any, Transfer]:
    """Match the image position `click` (Click: image id, col, row) into the `targets` (default: every
    other image of `images`). images: {image id: raster path (or matching.imagery.Image)}; models:
    {image id: sensor model}; height: ellipsoidal height (m) of the point, or (h_min, h_max) to
    search over (default: the source model's own height range, RPC); params: GrowParams (template,
    acceptance criteria, resolution adaptation); radius: px searched around the prediction with a
    height. Returns {target id: Transfer}."""
    source_id, col, row = click
    params = (params or GrowParams()).check()
    targets = [t for t in images if t != source_id] if targets is None else list(targets)
    for key in [source_id] + targets:
        if key not in images or key not in models:
            raise InputError(
                f"image {key} is not among the images with a raster and a model ({sorted(set(images) & set(models))})"
            )
    source = as_image(images[source_id])
    cols, rows = source.size
    col, row = float(col), float(row)
    if not (0.0 <= col <= cols and 0.0 <= row <= rows):
        raise InputError(f"({col:.1f}, {row:.1f}) lies outside image {source_id} ({cols} x {rows} px)")
    fixed = height is not None and np.ndim(height) == 0
    if height is None and getattr(models[source_id], "height_range", None) is None:
        raise InputError(
            "the terrain height is unknown: give the point's height, or the block's height range (h_min, h_max)"
        )
    hr = (float(cast(float, height)),) * 2 if fixed else HeightRange.resolve(height, models[source_id]).bounds
    out = {}
    for target_id in targets:
        model1, model2 = models[source_id], models[target_id]
        target = as_image(images[target_id])
        x2 = y2 = None
        if fixed:
            x2, y2 = (np.atleast_1d(v) for v in predict(model1, model2, col, row, hr[0]))
            c2, r2 = target.size
            if not (
                np.isfinite(x2[0])
                and np.isfinite(y2[0])
                and -radius <= x2[0] <= c2 + radius
                and -radius <= y2[0] <= r2 + radius
            ):
                out[target_id] = _failed(f"the sensor models place the point outside image {target_id}")
                continue
        image1, image2 = adapt_resolution(source, target, model1, model2, params, hr)
        rec, ok = seeds_from_points(
            ImagePair(image1, image2, model1, model2), [col], [row], params, hr, x2=x2, y2=y2, radius=radius
        )
        r = rec[0]
        out[target_id] = Transfer(
            float(r["x2"]),
            float(r["y2"]),
            float(r["rho"]),
            float(r["semi_major"]),
            bool(ok[0]),
            "" if ok[0] else _reason(r, params),
        )
    return out
