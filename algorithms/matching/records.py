"""Record layouts shared by the matchers (numpy structured dtypes, so millions of points stay
compact and vectorised).

PAIR_DTYPE: one point matched from a reference image (1) into a search image (2): positions,
quality (rho, error-ellipse semi-axes in px of image 2, iterations, shift from the initial
values) and the final affine parameters, which seed the neighbours' initial values:
x2(k, l) = x2 + a1 k + a2 l, y2(k, l) = y2 + a4 k + a5 l for template offsets (k, l) in px of
image 1."""

import numpy as np

PAIR_DTYPE = np.dtype(
    [
        ("x1", "f8"),
        ("y1", "f8"),
        ("x2", "f8"),
        ("y2", "f8"),
        ("rho", "f4"),
        ("semi_major", "f4"),
        ("semi_minor", "f4"),
        ("shift", "f4"),
        ("iterations", "i2"),
        ("a1", "f4"),
        ("a2", "f4"),
        ("a4", "f4"),
        ("a5", "f4"),
        ("r0", "f4"),
        ("r1", "f4"),
        ("seed", "i4"),
    ]
)
