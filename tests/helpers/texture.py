"""A band-limited random texture for matching tests and studies: exactly evaluable at any position,
also through a Gaussian low-pass."""

import numpy as np

#: positions evaluated at once
CHUNK = 20000


def texture(rng, ncomp=150, sigma_freq=0.06):
    """A continuous band-limited random texture (unit variance, Gaussian spectrum with standard
    deviation sigma_freq cycles/px per axis), exactly evaluable anywhere; f(x, y, blur) is the
    texture seen through a Gaussian low-pass of (sigma_x, sigma_y) = blur px."""
    u, v = rng.normal(0, sigma_freq, ncomp), rng.normal(0, sigma_freq, ncomp)
    phase = rng.uniform(0, 2 * np.pi, ncomp)
    amp = np.sqrt(2.0 / ncomp)

    def f(x, y, blur=(0.0, 0.0)):
        att = amp * np.exp(-2 * np.pi**2 * (blur[0] ** 2 * u**2 + blur[1] ** 2 * v**2))
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        out = np.empty(x.shape)
        fx, fy, fo = x.ravel(), y.ravel(), out.reshape(-1)
        for a in range(0, fx.size, CHUNK):  # CHUNK x ncomp phases at a time: bounded memory
            s = slice(a, a + CHUNK)
            arg = 2 * np.pi * (np.multiply.outer(fx[s], u) + np.multiply.outer(fy[s], v)) + phase
            fo[s] = (att * np.cos(arg)).sum(-1)
        return out

    return f
