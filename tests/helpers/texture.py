"""A band-limited random texture for matching tests and studies: exactly evaluable at any position,
also through a Gaussian low-pass."""
import numpy as np


def texture(rng, ncomp=150, sigma_freq=0.06):
    """A continuous band-limited random texture (unit variance, Gaussian spectrum with standard
    deviation sigma_freq cycles/px per axis), exactly evaluable anywhere; f(x, y, blur) is the
    texture seen through a Gaussian low-pass of (sigma_x, sigma_y) = blur px."""
    u, v = rng.normal(0, sigma_freq, ncomp), rng.normal(0, sigma_freq, ncomp)
    phase = rng.uniform(0, 2 * np.pi, ncomp)
    amp = np.sqrt(2.0 / ncomp)

    def f(x, y, blur=(0.0, 0.0)):
        att = amp * np.exp(-2 * np.pi ** 2 * (blur[0] ** 2 * u ** 2 + blur[1] ** 2 * v ** 2))
        return (att * np.cos(2 * np.pi * (np.multiply.outer(x, u) + np.multiply.outer(y, v)) + phase)).sum(-1)
    return f
