"""The execution layer (algorithms/execution.py): the same results in the same order on threads, local
processes and a Dask LocalCluster; progress, cancel, task errors, a dying worker, a scheduler that
does not answer, and worker processes started from a host program that is not Python (QGIS)."""
import os
import sys
import time

import numpy as np
import pytest

from pushbroom.algorithms import execution, raster_cache
from pushbroom.algorithms.errors import CancelledError, ExecutionError, InputError
from pushbroom.algorithms.execution import Execution, run_tasks
from tests.helpers import execution_tasks as tasks
from tests.helpers.feedback import Feedback

BACKENDS = [Execution("threads", 2), Execution("processes", 2), Execution("dask", 2)]


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_every_backend_returns_the_numpy_results_in_task_order(where):
    log = Feedback()
    out = run_tasks(tasks.statistic, [(seed, 1000) for seed in range(12)], where, log)
    # the plain numpy reference, in this process, bit for bit
    reference = [(s, float(np.random.default_rng(s).standard_normal(1000).mean())) for s in range(12)]
    assert [r[:2] for r in out] == reference
    pids = {r[2] for r in out}
    assert (pids == {os.getpid()}) == (where.backend == "threads")     # processes ran elsewhere
    assert log.progress[-1] == 100.0 and len(log.progress) == 12          # one step per finished task
    assert log.messages == [f"the tiles: 12 tasks on {where.describe()}"]


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_worker_processes_hold_gdals_cache_to_the_steps_bound(where):
    from osgeo import gdal
    default = gdal.GetCacheMax()
    if default <= raster_cache.STEP_CACHE:
        pytest.skip(f"GDAL's cache here ({default} bytes, 5 % of the RAM) is below the steps' bound already")
    assert {c for _, c in run_tasks(tasks.gdal_cache, [(k,) for k in range(4)], where)} == {raster_cache.STEP_CACHE}
    with raster_cache.bounded():                    # the step's own process, inside the block only
        assert gdal.GetCacheMax() == raster_cache.STEP_CACHE
    assert gdal.GetCacheMax() == default


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_worker_processes_return_freed_memory_to_the_system(where):
    name = "MALLOC_TRIM_THRESHOLD_"
    before = os.environ.get(name)
    assert {v for v in run_tasks(tasks.environment, [(name,)] * 4, where)} == {execution.WORKER_ENVIRONMENT[name]}
    assert os.environ.get(name) == before                     # this process's environment as it was


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_what_every_task_shares_is_sent_once(where):
    job = {"values": np.arange(200_000, dtype=float)}
    tasks_ = [(job, k) for k in range(6)]
    assert run_tasks(tasks.weighted_sum, tasks_, where) == [k * float(job["values"].sum()) for k in range(6)]
    if where.backend != "dask":
        return
    with execution.session(where):
        backend = execution._sessions[(execution.threading.get_ident(), where)]
        submitted, shared = backend.prepare(tasks_)
        assert len(shared) == 1 and all(t[0] is shared[0] and t[1] == k for k, t in enumerate(submitted))
        assert type(shared[0]).__name__ == "Future"             # the job travels once, as a future


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_a_session_keeps_the_workers_across_rounds(where):
    with execution.session(where):
        rounds = [{r[2] for r in run_tasks(tasks.statistic, [(s, 100) for s in range(8)], where)} for _ in range(3)]
    kept = set().union(*rounds)
    assert len(kept) <= 2 and os.getpid() not in kept          # the session's 2 workers ran every round
    outside = [{r[2] for r in run_tasks(tasks.statistic, [(s, 100) for s in range(8)], where)} for _ in range(2)]
    assert not outside[0] & kept and not outside[0] & outside[1]          # closed at its end; new workers each time


def test_an_execution_says_where_it_runs():
    assert [e.describe() for e in BACKENDS] == ["2 threads", "2 local worker processes",
                                                "a Dask local cluster of 2 worker processes"]
    assert Execution("dask", 1, "tcp://10.0.0.5:8786").describe() == "the Dask cluster at tcp://10.0.0.5:8786"
    assert Execution("threads", 1).describe() == "1 thread"


@pytest.mark.parametrize("where", BACKENDS[:2], ids=lambda e: e.backend)
def test_a_cancel_stops_the_pending_tasks(where, tmp_path):
    stop = Feedback(cancel_at=1.0)                  # cancelled once the first task has finished
    with pytest.raises(CancelledError):
        run_tasks(tasks.slow_marker, [(str(tmp_path), k, 0.3) for k in range(20)], where, stop)
    time.sleep(1.0)
    # only the tasks a worker had started or queued ran: the first two (finishing together), the 2 running
    # then, and for processes the pool's call queue (workers + 1, which concurrent.futures cannot cancel);
    # the 13 or more others never ran
    assert len(os.listdir(tmp_path)) <= 2 + 2 + (3 if where.backend == "processes" else 0)


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_a_task_error_is_raised_as_it_is(where):
    with pytest.raises(InputError, match="task 2 refuses"):
        run_tasks(tasks.refuse, [(k,) for k in range(6)], where)


def test_dask_reruns_the_task_of_a_killed_worker(tmp_path):
    out = run_tasks(tasks.die_once, [(str(tmp_path), k) for k in range(6)], Execution("dask", 2))
    assert (tmp_path / "died-1").exists()            # the worker did die
    assert out == [k * k for k in range(6)]          # and the run completed with every result


def test_a_process_pool_names_a_dead_worker(tmp_path):
    with pytest.raises(ExecutionError, match="worker process .* died"):
        run_tasks(tasks.die_once, [(str(tmp_path), k) for k in range(6)], Execution("processes", 2), what="the test")


def test_a_scheduler_that_does_not_answer_is_a_clear_error():
    start = time.monotonic()
    with pytest.raises(ExecutionError, match="no Dask scheduler answers at tcp://127.0.0.1:9 within 3 s"):
        run_tasks(tasks.refuse, [(0,)], Execution("dask", 2, address="tcp://127.0.0.1:9", connect_timeout=3))
    assert time.monotonic() - start < 30       # the bound: an error, not a hang


@pytest.mark.parametrize("host", ["/usr/bin/qgis", "/root/.pyenv/shims/python3"])
def test_worker_processes_start_this_python_when_the_host_is_not_it(monkeypatch, host):
    # QGIS reports its binary, or (embedded Python) the first python3 on PATH, maybe another installation's
    monkeypatch.setattr(sys, "executable", host)
    exe = execution.python_executable()
    assert exe.startswith(sys.exec_prefix + os.sep) and os.path.basename(exe).startswith("python")   # this venv's
    out = run_tasks(tasks.statistic, [(1, 10), (2, 10)], Execution("processes", 2))
    assert [r[0] for r in out] == [1, 2]


@pytest.mark.parametrize("bad, message", [(Execution("cluster"), "must be one of threads, processes, dask"),
                                          (Execution("threads", 0), "at least one worker"),
                                          (Execution("threads", address="tcp://h:8786"), "is for the dask execution")])
def test_settings_no_backend_can_use_are_refused(bad, message):
    with pytest.raises(InputError, match=message):
        bad.check()
