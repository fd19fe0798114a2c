"""Module-level tile tasks for tests/algorithms/test_execution.py (worker processes import them)."""

import os
import time

import numpy as np

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.task_runtime import check_cancel


def statistic(seed, n):
    """(seed, the mean of n standard normals drawn with `seed`, the worker's pid)."""
    return seed, float(np.random.default_rng(seed).standard_normal(n).mean()), os.getpid()


def slow_marker(folder, k, seconds):
    """Sleep, then leave the file <folder>/<k> (the task ran to its end); returns k."""
    time.sleep(seconds)
    with open(os.path.join(folder, str(k)), "w"):
        pass
    return k


def refuse(k):
    """An engine error in the third task."""
    if k == 2:
        raise InputError(f"task {k} refuses")
    return k


def die_once(folder, k):
    """Task 1 kills its own worker process (SIGKILL) the first time it runs, as the OOM killer would."""
    marker = os.path.join(folder, f"died-{k}")
    if k == 1 and not os.path.exists(marker):
        with open(marker, "w"):
            pass
        os.kill(os.getpid(), 9)
    time.sleep(0.2)
    return k * k


def gdal_cache(k):
    """(k, the GDAL block cache limit of the process running the task, in bytes)."""
    from osgeo import gdal

    return k, gdal.GetCacheMax()


def environment(name):
    """The worker's value of the environment variable `name` (None: unset)."""
    return os.environ.get(name)


def weighted_sum(job, k):
    """k times the sum of the array job["values"] (a job every task shares)."""
    return k * float(job["values"].sum())


def staged(folder, k, stages, seconds, blob=b""):
    """Leave <folder>/pid-<k> with the worker's pid, then run `stages` stages of `seconds` each: before each, a
    look at the cancel token (task_runtime.check_cancel) as the steps' tile functions do; after each, the file
    <folder>/<k>.<stage>. `blob` is an argument to carry (a large one fills a pipe). Returns k."""
    with open(os.path.join(folder, f"pid-{k}"), "w") as f:
        f.write(str(os.getpid()))
    for stage in range(stages):
        check_cancel()
        time.sleep(seconds)
        with open(os.path.join(folder, f"{k}.{stage}"), "w"):
            pass
    return k


def warning_action(message, category):
    """What the worker's warning filters do with a warning `message` of the builtin `category` (its name): the
    action of the first filter that matches it ("ignore", "default", ...)."""
    import builtins
    import warnings

    kind = getattr(builtins, category)
    for action, text, of, _, _ in warnings.filters:
        if (text is None or text.match(message)) and issubclass(kind, of):
            return action
    return warnings.defaultaction


def pid_after(seconds):
    """The worker's pid, after sleeping `seconds`."""
    time.sleep(seconds)
    return os.getpid()


def long_first_time(job, folder, k, seconds):
    """Leave <folder>/pid-<k> with the worker's pid; the first run of task k (no <folder>/ran-<k> yet) then runs
    `seconds` in stages of 0.1 s with a look at the cancel token before each, a later run (the task run again after
    its worker died) at once; leave <folder>/done-<k>. Returns k times the sum of job["values"]."""
    with open(os.path.join(folder, f"pid-{k}"), "w") as f:
        f.write(str(os.getpid()))
    first = not os.path.exists(os.path.join(folder, f"ran-{k}"))
    with open(os.path.join(folder, f"ran-{k}"), "w"):
        pass
    for _ in range(int(seconds / 0.1) if first else 0):
        check_cancel()
        time.sleep(0.1)
    with open(os.path.join(folder, f"done-{k}"), "w"):
        pass
    return k * float(job["values"].sum())


def after_gate(job, folder, k, seconds):
    """Leave <folder>/started-<k>; wait until <folder>/go exists (looking every 0.05 s, with a look at the cancel
    token; 120 s at most, so that a test that never opens the gate fails instead of hanging), then `seconds`; leave
    <folder>/done-<k>. Returns k times the sum of job["values"]."""
    with open(os.path.join(folder, f"started-{k}"), "w"):
        pass
    deadline = time.monotonic() + 120.0
    while not os.path.exists(os.path.join(folder, "go")) and time.monotonic() < deadline:
        check_cancel()
        time.sleep(0.05)
    time.sleep(seconds)
    with open(os.path.join(folder, f"done-{k}"), "w"):
        pass
    return k * float(job["values"].sum())


def name_of(kind, k):
    """`kind`'s name and `k`: a task whose first argument is a class (a matching strategy's tasks are)."""
    return f"{kind.__name__}-{k}"
