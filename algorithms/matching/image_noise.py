"""The noise of an image: the standard deviation of its grey values' random part, in DN.

Immerkaer's estimator: the image convolved with the difference of two Laplacians,

    L = [[1, -2, 1], [-2, 4, -2], [1, -2, 1]],

cancels any surface up to a plane's curvature and leaves white noise of variance 36 sigma^2. Texture leaks
through it, and more so where the texture is strong (edges, roofs, crowns): the robust form, 1.4826 MAD of the
responses / 6, takes the bulk of an image's pixels, which are smooth at the 3 x 3 scale, and ignores that tail.
Masked pixels (NaN) give no response.

`image_noise` pools the responses of a fixed set of windows spread evenly over the image (WINDOWS of
WINDOW px, all of a smaller image): one value per image, the same for every tile of it. It assumes that the
noise does not depend on the grey level, which holds for the simulated images and roughly for the
radiometrically corrected products (a photon noise term grows with the signal: a scene of very dark and very
bright areas gets their mixture). Flat fill that is not masked (a constant border without a nodata value) gives
zero responses and lowers the estimate; restored and resampled pixels (real Pleiades products) carry correlated
noise, of which the 3 x 3 kernel sees only the high-frequency part.

Reference: J. Immerkaer, "Fast noise variance estimation", Computer Vision and Image Understanding 64(2),
300-302, 1996."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from .imagery import Image

#: Immerkaer's kernel (module docstring)
LAPLACE_DIFFERENCE = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
#: windows per image side (WINDOWS^2 in all) and their size (px)
WINDOWS, WINDOW = 4, 256


def responses(data: np.ndarray) -> np.ndarray:
    """The finite responses of the 2-D array `data` to LAPLACE_DIFFERENCE (valid part only; NaN where a
    masked pixel is in the 3 x 3)."""
    if min(data.shape) < 3:
        return np.zeros(0)
    out = ndimage.correlate(np.asarray(data, float), LAPLACE_DIFFERENCE, mode="constant")[1:-1, 1:-1]
    return out[np.isfinite(out)]


def robust_sigma(values: np.ndarray) -> float:
    """1.4826 MAD / 6 of Immerkaer's `values` (module docstring); NaN for none."""
    if values.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(values - np.median(values))) / 6.0)


def image_noise(image: Image) -> float:
    """The noise sigma (DN) of the Image-like `image` (module docstring); NaN where no window has a 3 x 3 of
    valid pixels."""
    cols, rows = image.size
    parts = []
    for y0 in _starts(rows):
        for x0 in _starts(cols):
            data, _, _ = image.read(x0, y0, WINDOW, WINDOW)
            parts.append(responses(data))
    return robust_sigma(np.concatenate(parts))


def _starts(size: int) -> list[int]:
    """WINDOWS evenly spread window starts along an axis of `size` px (one at 0 where WINDOWS windows cover it)."""
    if size <= WINDOWS * WINDOW:
        return list(range(0, size, WINDOW))
    return [int(round(v)) for v in np.linspace(0, size - WINDOW, WINDOWS)]
