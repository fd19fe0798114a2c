"""The dask execution on a cluster that misbehaves (algorithms/dask_backend.py): a scheduler and workers started
by the test as separate processes (`dask scheduler`, `dask worker`), as a user's cluster. Each case gives the
threads' result or a clear ExecutionError, within a bounded time: the last busy worker killed after the other has
idled (the shared job then has its only copy there), every worker killed mid-step, a scheduler without workers, a
worker without pushbroom, a worker added during a step."""

import os
import re
import subprocess
import sys
import time

import numpy as np
import pytest

from pushbroom.algorithms.errors import ExecutionError
from pushbroom.algorithms.execution import Execution, run_tasks
from tests.helpers import execution_tasks as tasks
from tests.helpers.dask_cluster import Cluster
from tests.helpers.feedback import Feedback
from tests.helpers.processes import pid_in, when

#: the wait for a worker the tests give (s): a cluster without one fails after it
WAIT = 3.0
#: the bound on a failed round: the wait, a look at the workers every second, the start of a client, with room for a
#: loaded machine; a hang would be minutes
BOUND = WAIT + 60.0

pytestmark = pytest.mark.slow


@pytest.fixture
def cluster(tmp_path):
    with Cluster(tmp_path) as started:
        yield started


def _job():
    return {"values": np.arange(100_000, dtype=float)}


def _tasks(job, folder, seconds):
    """The round's tasks: (job, folder, k, seconds of the first run) for each k of `seconds`."""
    return [(job, str(folder), k, s) for k, s in enumerate(seconds)]


def _threads_result(job, n):
    return run_tasks(tasks.weighted_sum, [(job, k) for k in range(n)], Execution("threads", 2))


def _pid_of(folder, k):
    return pid_in(folder / f"pid-{k}")


def test_the_last_busy_worker_killed_after_the_other_idled_gives_the_threads_result(cluster, tmp_path):
    workers = [cluster.add_worker(), cluster.add_worker()]
    cluster.wait_for_workers(2)
    folder = tmp_path / "tasks"
    folder.mkdir()
    job, log = _job(), Feedback()
    idle_since = {}

    def kill_the_busy_one():
        # the short task's worker has idled 5 s (Dask's memory manager drops extra replicas every 2 s): the job's
        # one copy is on the worker of the long task, which dies now
        busy = _pid_of(folder, 1)
        assert busy is not None and (folder / "done-0").exists() and not (folder / "done-1").exists()
        Cluster.kill(next(w for w in workers if w.pid == busy))

    def ready():
        if (folder / "done-0").exists():
            idle_since.setdefault("t", time.monotonic())
        return "t" in idle_since and time.monotonic() - idle_since["t"] >= 5.0 and _pid_of(folder, 1) is not None

    killer = when(ready, kill_the_busy_one)
    out = run_tasks(
        tasks.long_first_time,
        _tasks(job, folder, [0.5, 60.0]),
        Execution("dask", address=cluster.address, worker_wait=WAIT),
        log,
        what="the test",
    )
    killer.join(1)
    assert sum(w.poll() is not None for w in workers) == 1  # the busy worker did die, mid-task
    assert out == _threads_result(job, 2)  # and the run completed with every result
    left = [m for m in log.messages if " left the Dask cluster" in m]
    assert len(left) == 1 and "its running tiles run again on another (1 worker left)" in left[0]
    assert re.fullmatch(r"the test: tasks per worker: tcp://127\.0\.0\.1:\d+ 2", log.messages[-1])


@pytest.mark.parametrize("n", [1, 4], ids=["one task", "four tasks"])
def test_every_worker_killed_mid_step_is_a_clear_error_within_the_wait(cluster, tmp_path, n):
    workers = [cluster.add_worker(), cluster.add_worker()]
    cluster.wait_for_workers(2)
    folder = tmp_path / "tasks"
    folder.mkdir()
    log = Feedback()
    running = min(n, 2)
    when(
        lambda: sum(_pid_of(folder, k) is not None for k in range(n)) >= running,
        lambda: Cluster.kill(*workers),
    )
    start = time.monotonic()
    with pytest.raises(ExecutionError) as failed:
        run_tasks(
            tasks.long_first_time,
            _tasks(_job(), folder, [60.0] * n),
            Execution("dask", address=cluster.address, worker_wait=WAIT),
            log,
            what="dense matching's tiles",
        )
    assert time.monotonic() - start < BOUND  # an error, not a wait for workers that never come
    assert str(failed.value) == (
        f"dense matching's tiles: every worker of the Dask cluster at {cluster.address} was lost, and none came back "
        f"within {WAIT:g} s (0 workers connected): start one on a host that sees the same files, `python3 -m "
        f"distributed.cli.dask_worker {cluster.address} --nthreads 1` (README, Scaling out), or raise the wait "
        f"(DASK_WAIT); 0 of {n} task{'s' * (n != 1)} finished, nothing was stored: the block and the outputs are as "
        "they were"
    )
    assert (
        f"dense matching's tiles: every worker of the Dask cluster at {cluster.address} is lost: waiting up to "
        f"{WAIT:g} s for one to come back" in log.messages
    )
    assert not list(folder.glob("done-*"))


@pytest.mark.parametrize("n", [1, 4], ids=["one task", "four tasks"])
def test_a_scheduler_without_workers_is_a_clear_error_after_the_wait(cluster, tmp_path, n):
    log = Feedback()
    start = time.monotonic()
    with pytest.raises(ExecutionError) as failed:
        run_tasks(
            tasks.long_first_time,
            _tasks(_job(), tmp_path, [0.0] * n),
            Execution("dask", address=cluster.address, worker_wait=WAIT),
            log,
            what="the DEM's tiles",
        )
    assert WAIT <= time.monotonic() - start < BOUND
    assert str(failed.value).startswith(
        f"the DEM's tiles: no worker joined the Dask cluster at {cluster.address} within {WAIT:g} s (0 workers "
        f"connected): start one on a host that sees the same files, `python3 -m distributed.cli.dask_worker "
        f"{cluster.address} --nthreads 1`"
    )
    assert str(failed.value).endswith(
        f"(DASK_WAIT); 0 of {n} task{'s' * (n != 1)} finished, nothing was stored: the "
        "block and the outputs are as they were"
    )
    assert log.messages[1:] == [
        f"the Dask cluster at {cluster.address} has no worker: waiting up to {WAIT:g} s for one"
    ]
    assert not list(tmp_path.glob("pid-*"))


def test_a_worker_without_pushbroom_is_named_before_any_task_runs(cluster, tmp_path):
    cluster.add_worker()
    # Debian's Python with its Dask, but neither the venv (numba, CNES libsgm) nor the plugin
    bare = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    cluster.add_worker(python="/usr/bin/python3", env=bare)
    cluster.wait_for_workers(2)
    with pytest.raises(ExecutionError) as failed:
        run_tasks(
            tasks.long_first_time,
            _tasks(_job(), tmp_path, [0.0] * 4),
            Execution("dask", address=cluster.address, worker_wait=WAIT),
            what="the test",
        )
    message = str(failed.value)
    assert message.startswith(
        f"the test: 1 of 2 workers of the Dask cluster at {cluster.address} cannot run "
        "Pushbroom's tasks: tcp://127.0.0.1:"
    )
    assert "no pushbroom (ModuleNotFoundError: No module named 'pushbroom': install the plugin's wheel" in message
    assert "no numba (ModuleNotFoundError: No module named 'numba'" in message
    assert len(re.findall(r"tcp://127\.0\.0\.1:\d+ on [^:]+: Python [^)]+\), no Pushbroom: no pushbroom", message)) == 1
    assert message.endswith("0 of 4 tasks finished, nothing was stored: the block and the outputs are as they were")
    assert not list(tmp_path.glob("pid-*"))  # no task ran, not even on the good worker
    # the README's one command for checking the workers says the same
    checked = subprocess.run(
        [sys.executable, "-m", "pushbroom.algorithms.worker_check", cluster.address],
        capture_output=True,
        text=True,
        timeout=120,
    )
    lines = checked.stdout.splitlines()
    assert checked.returncode == 1 and lines[-1] == "1 of 2 workers run Pushbroom " + _version()
    assert sum(", no Pushbroom: FAILS: no pushbroom" in line for line in lines) == 1
    assert (
        sum(line.endswith(f": Python {_python()} ({sys.executable}), Pushbroom {_version()}: ok") for line in lines)
        == 1
    )


def _version():
    from pushbroom import __version__

    return __version__


def _python():
    import platform

    return platform.python_version()


def test_a_worker_added_during_a_step_takes_tasks_and_gives_the_threads_result(cluster, tmp_path):
    cluster.add_worker()
    cluster.wait_for_workers(1)
    folder = tmp_path / "tasks"
    folder.mkdir()
    job, log = _job(), Feedback()

    def add_a_worker():
        # a task has started on the first worker and waits, the others are queued: a second worker joins, then
        # they go on
        cluster.add_worker()
        cluster.wait_for_workers(2)
        (folder / "go").touch()

    when(lambda: any(folder.glob("started-*")), add_a_worker)
    out = run_tasks(
        tasks.after_gate,
        _tasks(job, folder, [1.0] * 8),
        Execution("dask", address=cluster.address, worker_wait=WAIT),
        log,
        what="the test",
    )
    assert out == _threads_result(job, 8)
    joined = [
        re.fullmatch(r"the test: worker (\S+) joined the Dask cluster at \S+ \(2 workers\)", m) for m in log.messages
    ]
    assert sum(map(bool, joined)) == 1
    new = next(j for j in joined if j)[1]
    assert log.messages[-1].startswith("the test: tasks per worker: ")
    ran = dict(re.findall(r"(tcp://\S+) (\d+)", log.messages[-1]))
    assert sum(map(int, ran.values())) == 8 and int(ran.get(new, 0)) >= 1, log.messages  # the new one ran some
