"""Preprocessing of a 6000 x 6000 uint16 image: Saint-Marc x3, Wallis, 4-level pyramid, whole chain.
algorithms/matching/preprocess.py: Saint-Marc smoothing (3 iterations, k from the image), Wallis filter
(21 px window), 4-level pyramid (factor 3), and the chain of the three; seconds and Mpx/s with 1 and 2
numba threads. Best of three after JIT warm-up."""

import numpy as np

from pushbroom.algorithms.matching import preprocess
from tests.benchmarks.benchutil import best_time, thread_counts

SIZE = 6000


def chain(img):
    return preprocess.pyramid(preprocess.wallis(preprocess.saint_marc(img, iterations=3)), 4)


def run():
    rng = np.random.default_rng(0)
    img = (2000 + rng.normal(0, 300, (SIZE, SIZE))).clip(0, 4095).astype(np.uint16)  # 12-bit data
    smooth = preprocess.saint_marc(img, iterations=3)
    steps = (
        ("saint_marc x3", lambda: preprocess.saint_marc(img, iterations=3)),
        ("wallis 21", lambda: preprocess.wallis(smooth)),
        ("pyramid 4 levels", lambda: preprocess.pyramid(smooth, 4)),
        ("chain", lambda: chain(img)),
    )
    rows = []
    for threads in thread_counts():
        for name, call in steps:
            seconds = best_time(call)
            rows.append(
                {
                    "operation": name,
                    "threads": threads,
                    "pixels": img.size,
                    "seconds": seconds,
                    "Mpx/s": img.size / seconds / 1e6,
                }
            )
    return rows
