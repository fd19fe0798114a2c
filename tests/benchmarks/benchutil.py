"""Helpers shared by the bench_*.py modules."""

import os
import pathlib
import time

import numba

#: the real test data ($PUSHBROOM_SHARED_DATA, by default the data folder of the shared folder beside the repository)
SHARED_DATA = pathlib.Path(
    os.environ.get("PUSHBROOM_SHARED_DATA", pathlib.Path(__file__).resolve().parents[3] / "shared" / "data")
)


def best_time(function, repeat=3):
    """Shortest wall time of `repeat` calls of function(), after one warm-up call (JIT compilation
    or numba cache load)."""
    function()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def thread_counts(counts=(1, 2)):
    """Yield each numba thread count of `counts` the machine has, with numba set to it; the count
    before is restored afterwards."""
    saved = numba.get_num_threads()
    try:
        for threads in counts:
            if threads <= numba.config.NUMBA_NUM_THREADS:
                numba.set_num_threads(threads)
                yield threads
    finally:
        numba.set_num_threads(saved)
