"""Module-level tile tasks for tests/algorithms/test_execution.py (worker processes import them)."""
import os
import time

import numpy as np

from pushbroom.algorithms.errors import InputError


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
