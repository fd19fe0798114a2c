"""A pytest plugin that times numba's compilation: each process (an xdist worker too) writes the seconds it spent
compiling each top-level jitted function (its callees' compilation included) to
build/numba-compile-times/<pid>.txt, the slowest first. For the suite's time, on a clean clone (no numba cache):

    .venv/bin/python -m pytest -q -n 2 --dist loadgroup -p tests.helpers.numba_compile_times tests

Written at pytest_unconfigure: tests/conftest.py ends the process with os._exit, so atexit would not run."""

import collections
import os
import pathlib
import time

from numba.core import event

OUT = pathlib.Path(__file__).resolve().parents[2] / "build" / "numba-compile-times"
_SECONDS: dict[str, float] = collections.defaultdict(float)
_STARTS: list[float] = []


class _Timer(event.Listener):
    def on_start(self, ev):
        _STARTS.append(time.perf_counter())

    def on_end(self, ev):
        start = _STARTS.pop()
        if not _STARTS:  # a top-level compilation: its callees' are inside it
            func = getattr(ev.data.get("dispatcher"), "py_func", None)
            name = f"{func.__module__}.{func.__qualname__}" if func is not None else "?"
            _SECONDS[name] += time.perf_counter() - start


event.register("numba:compile", _Timer())


def pytest_unconfigure(config):
    OUT.mkdir(parents=True, exist_ok=True)
    rows = sorted(_SECONDS.items(), key=lambda kv: -kv[1])
    (OUT / f"{os.getpid()}.txt").write_text(
        f"{sum(_SECONDS.values()):8.1f} total\n" + "".join(f"{v:8.1f} {k}\n" for k, v in rows)
    )
