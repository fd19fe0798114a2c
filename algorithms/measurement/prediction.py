"""Where a ground point appears in the block's images, and which ground point a click in an image
shows: the sensor models' ground_to_image, and image_to_ground at a height or image_to_dem (the
first intersection of the line of sight with a DEM, sensors/base.py)."""

import math

import numpy as np

from ..errors import GeometryError, InputError


def predict(models, lon, lat, h):
    """{image id: (col, row)} of the ground point (WGS 84 lon, lat degrees, ellipsoidal h m) in the
    images of `models` ({image id: sensor model}); None for an image the point falls outside of
    (or whose model has no position for it)."""
    out = {}
    for image_id, model in models.items():
        col, row = (float(v) for v in model.ground_to_image(float(lon), float(lat), float(h)))
        cols, rows = model.size
        inside = math.isfinite(col) and math.isfinite(row) and 0.0 <= col <= cols and 0.0 <= row <= rows
        out[image_id] = (col, row) if inside else None
    return out


def ground_from_click(model, col, row, dem=None, height=0.0):
    """(lon, lat, h) seen at image position (col, row): where its line of sight first meets `dem`
    (algorithms.dem.Dem of ellipsoidal heights), or, without one, at the ellipsoidal `height` (m).
    InputError where there is no such ground point (a ray missing the DEM, outside the model's
    domain)."""
    try:
        if dem is not None:
            lon, lat, h = (float(np.asarray(v)) for v in model.image_to_dem(float(col), float(row), dem))
        else:
            h = float(height)
            lon, lat = (float(np.asarray(v)) for v in model.image_to_ground(float(col), float(row), h))
    except GeometryError as exc:
        raise InputError(f"no ground point for image position ({col:.2f}, {row:.2f}): {exc}") from exc
    if not all(math.isfinite(v) for v in (lon, lat, h)):
        raise InputError(
            f"no ground point for image position ({col:.2f}, {row:.2f}): it lies outside the sensor model's domain"
        )
    return lon, lat, h
