"""The image noise estimate (matching/image_noise.py) against images of known noise."""

import numpy as np
import pytest

from pushbroom.algorithms.matching.image_noise import WINDOW, WINDOWS, image_noise, responses, robust_sigma
from pushbroom.algorithms.matching.imagery import Image


def smooth(rows, cols):
    """A surface the kernel cancels: a plane and a gentle curvature (DN)."""
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    return 300.0 + 0.2 * x - 0.1 * y + 2e-4 * (x - cols / 2) ** 2


def test_white_noise_on_a_smooth_surface_is_measured():
    rng = np.random.default_rng(5)
    image = smooth(700, 900) + rng.normal(0.0, 2.5, (700, 900))
    assert image_noise(Image(image)) == pytest.approx(2.5, rel=0.02)
    # the kernel's response is white noise of variance 36 sigma^2: its plain standard deviation says the same
    assert np.std(responses(image)) / 6.0 == pytest.approx(2.5, rel=0.02)


def test_texture_and_masked_pixels_do_not_raise_it():
    rng = np.random.default_rng(6)
    image = smooth(600, 600) + rng.normal(0.0, 1.5, (600, 600))
    # a third of the image under 6 px blocks of +-40 DN (roofs, crowns: edges everywhere), and a nodata patch
    blocks = 40.0 * np.sign(np.sin(np.arange(600)[:, None] // 6 * 1.7 + np.arange(600)[None, :] // 6 * 2.3))
    image[:, :200] += blocks[:, :200]
    image[300:400, 300:400] = np.nan
    plain = np.std(responses(image)) / 6.0
    assert plain > 2.0 * 1.5  # the edges dominate a plain estimate
    assert image_noise(Image(image)) == pytest.approx(1.5, rel=0.1)


def test_a_large_image_is_sampled_by_a_fixed_set_of_windows():
    rng = np.random.default_rng(7)
    rows, cols = 2 * WINDOWS * WINDOW, 3 * WINDOWS * WINDOW
    image = smooth(rows, cols) + rng.normal(0.0, 3.0, (rows, cols))
    reads = []

    class Counting(Image):
        def read(self, x0, y0, c, r):
            reads.append((x0, y0, c, r))
            return super().read(x0, y0, c, r)

    assert image_noise(Counting(image)) == pytest.approx(3.0, rel=0.03)
    assert len(reads) == WINDOWS * WINDOWS and {r[2:] for r in reads} == {(WINDOW, WINDOW)}
    xs, ys = sorted({r[0] for r in reads}), sorted({r[1] for r in reads})
    assert xs[0] == 0 and xs[-1] == cols - WINDOW and ys[0] == 0 and ys[-1] == rows - WINDOW


def test_nothing_to_measure_is_nan():
    assert np.isnan(image_noise(Image(np.full((50, 50), np.nan))))
    assert np.isnan(robust_sigma(np.zeros(0)))
