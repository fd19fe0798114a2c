"""The geometry of an image pair that both matchers share: where the sensor models put an image-1
point in image 2 at a height (`predict`), the local affine between the two images (`local_affine`)
and the search window a box of image 1 needs in image 2 (`search_box`), for an ImagePair.

Heights are ellipsoidal (m); image positions are GDAL's (pixel centres at half-integers). A position
outside a model's domain is NaN, never an error; a box none of whose predictions is finite has no
search window (None).

The search window is the bounding box of the predictions of a 5 x 5 grid over the image-1 box at the
lowest, middle and highest height of the range, widened by a margin: the models map a box to a smooth
quadrilateral per height, whose corners and edges the grid samples, and the middle height covers a
parallax that is not linear in height (curved rays, refraction). The margin covers what the prediction
cannot: the matching template, the search across the path, orientation errors."""

from typing import Any, NamedTuple

import numpy as np


class ImagePair(NamedTuple):
    """Two images (paths, arrays or Image-likes) and their sensor models: image 1 is matched into image 2."""

    image1: Any
    image2: Any
    model1: Any
    model2: Any


def predict(model1, model2, x1, y1, h):
    """Image-2 (x2, y2) of image-1 points (x1, y1) at ellipsoidal height(s) h (NaN outside)."""
    x1, y1, h = np.broadcast_arrays(np.asarray(x1, float), np.asarray(y1, float), np.asarray(h, float))
    lon, lat = model1.image_to_ground(x1.ravel().copy(), y1.ravel().copy(), h.ravel().copy())
    x2, y2 = model2.ground_to_image(np.asarray(lon), np.asarray(lat), h.ravel().copy())
    return np.asarray(x2, float).reshape(x1.shape), np.asarray(y2, float).reshape(x1.shape)


def local_affine(model1, model2, x1, y1, h, d=5.0):
    """Image-2 position and the affine (a1, a2, a4, a5) = d(x2, y2)/d(x1, y1) at height h, by
    central differences of `d` px. Returns (x2, y2, a1, a2, a4, a5) arrays."""
    x1 = np.atleast_1d(np.asarray(x1, float))
    y1 = np.atleast_1d(np.asarray(y1, float))
    h = np.broadcast_to(np.asarray(h, float), x1.shape)
    xs = np.concatenate([x1, x1 + d, x1 - d, x1, x1])
    ys = np.concatenate([y1, y1, y1, y1 + d, y1 - d])
    x2, y2 = predict(model1, model2, xs, ys, np.concatenate([h] * 5))
    n = x1.size
    c, px, mx, py, my = (slice(k * n, (k + 1) * n) for k in range(5))
    return (
        x2[c],
        y2[c],
        (x2[px] - x2[mx]) / (2 * d),
        (x2[py] - x2[my]) / (2 * d),
        (y2[px] - y2[mx]) / (2 * d),
        (y2[py] - y2[my]) / (2 * d),
    )


def search_box(model1, model2, box1, hr, margin):
    """(xa, ya, xb, yb), floats: the image-2 window that image 1's `box1` (x0, y0, x1, y1 px) needs
    over the height range `hr` (h_min, h_max), widened by `margin` px; None where no prediction is
    finite (the box misses image 2's model at every height)."""
    x0, y0, x1, y1 = box1
    gx, gy = (v.ravel() for v in np.meshgrid(np.linspace(x0, x1, 5), np.linspace(y0, y1, 5)))
    with np.errstate(invalid="ignore"):
        xy = [predict(model1, model2, gx, gy, np.full(gx.size, h)) for h in np.linspace(hr[0], hr[1], 3)]
    xs = np.concatenate([v[0] for v in xy])
    ys = np.concatenate([v[1] for v in xy])
    good = np.isfinite(xs) & np.isfinite(ys)
    if not good.any():
        return None
    return (xs[good].min() - margin, ys[good].min() - margin, xs[good].max() + margin, ys[good].max() + margin)
