"""Helpers shared by the bench_*.py scripts (run as scripts, so this folder is on sys.path)."""
import os
import pathlib
import time

#: the real test data (../shared/data beside the repository, or $PUSHBROOM_SHARED_DATA)
SHARED_DATA = pathlib.Path(os.environ.get("PUSHBROOM_SHARED_DATA",
                                          pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"))


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
