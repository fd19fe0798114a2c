"""The execution layer (algorithms/execution.py): the same results in the same order on threads, local
processes and a Dask LocalCluster; progress, cancel (also of the running tasks), task errors, a killed
worker, a scheduler that does not answer or a malformed address, the cap on the workers, and worker
processes started from a host program that is not Python (QGIS)."""

import collections
import os
import pathlib
import re
import signal
import sys
import time
from fractions import Fraction

import numpy as np
import pytest

from pushbroom.algorithms import dask_backend, execution, raster_cache, task_runtime
from pushbroom.algorithms.errors import CancelledError, ExecutionError, InputError
from pushbroom.algorithms.execution import Execution, run_tasks
from tests.helpers import execution_tasks as tasks
from tests.helpers.feedback import Feedback
from tests.helpers.processes import pid_in, when, worker_processes

BACKENDS = [Execution("threads", 2), Execution("processes", 2), Execution("dask", 2)]


def test_a_class_as_a_task_s_first_argument_is_passed_not_called():
    """Dask took an argument tuple that begins with a callable for a task of its own, and called it: the
    matching strategies' tasks on a cluster failed with 'RegionGrowing() takes no arguments' where a scene had
    one tile (several share the class through a future: DaskBackend.prepare)."""
    for count in (1, 3):
        out = run_tasks(tasks.name_of, [(Fraction, k) for k in range(count)], BACKENDS[2])
        assert out == [f"Fraction-{k}" for k in range(count)]


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_every_backend_returns_the_numpy_results_in_task_order(where):
    log = Feedback()
    out = run_tasks(tasks.statistic, [(seed, 1000) for seed in range(12)], where, log)
    # the plain numpy reference, in this process, bit for bit
    reference = [(s, float(np.random.default_rng(s).standard_normal(1000).mean())) for s in range(12)]
    assert [r[:2] for r in out] == reference
    pids = {r[2] for r in out}
    assert (pids == {os.getpid()}) == (where.backend == "threads")  # processes ran elsewhere
    assert log.progress[-1] == 100.0 and len(log.progress) == 12  # one step per finished task
    assert log.messages[0] == f"the tiles: 12 tasks on {where.describe()}"
    if where.backend != "dask":
        assert len(log.messages) == 1
        return
    # a cluster's log: its workers, then the tasks each ran (their pids' counts)
    named = re.fullmatch(r"the Dask local cluster: 2 workers \((tcp://\S+), (tcp://\S+)\)", log.messages[1])
    counts = re.fullmatch(r"the tiles: tasks per worker: (tcp://\S+) (\d+)(?:, (tcp://\S+) (\d+))?", log.messages[2])
    assert named and counts and len(log.messages) == 3
    tally = dict(zip(counts.groups()[::2], counts.groups()[1::2]))
    assert set(tally) - {None} <= set(named.groups())
    assert sorted(int(n) for n in tally.values() if n) == sorted(collections.Counter(r[2] for r in out).values())


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_worker_processes_hold_gdals_cache_to_the_steps_bound(where):
    from osgeo import gdal

    default = gdal.GetCacheMax()
    if default <= raster_cache.STEP_CACHE:
        pytest.skip(f"GDAL's cache here ({default} bytes, 5 % of the RAM) is below the steps' bound already")
    assert {c for _, c in run_tasks(tasks.gdal_cache, [(k,) for k in range(4)], where)} == {raster_cache.STEP_CACHE}
    with raster_cache.bounded():  # the step's own process, inside the block only
        assert gdal.GetCacheMax() == raster_cache.STEP_CACHE
    assert gdal.GetCacheMax() == default


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_worker_processes_return_freed_memory_to_the_system(where):
    name = "MALLOC_TRIM_THRESHOLD_"
    before = os.environ.get(name)
    assert {v for v in run_tasks(tasks.environment, [(name,)] * 4, where)} == {task_runtime.WORKER_ENVIRONMENT[name]}
    assert os.environ.get(name) == before  # this process's environment as it was


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_what_every_task_shares_is_sent_once(where):
    job = {"values": np.arange(200_000, dtype=float)}
    tasks_ = [(job, k) for k in range(6)]
    assert run_tasks(tasks.weighted_sum, tasks_, where) == [k * float(job["values"].sum()) for k in range(6)]
    if where.backend != "dask":
        return
    with execution.session(where):
        backend = execution._sessions[(execution.threading.get_ident(), where)]
        submitted = backend.prepare(tasks_)
        assert all(t[0] is submitted[0][0] and t[1] == k for k, t in enumerate(submitted))
        assert type(submitted[0][0]).__name__ == "Future"  # the job travels once, as a future


@pytest.mark.parametrize("where", BACKENDS[1:], ids=lambda e: e.backend)
def test_a_session_keeps_the_workers_across_rounds(where):
    with execution.session(where):
        rounds = [{r[2] for r in run_tasks(tasks.statistic, [(s, 100) for s in range(8)], where)} for _ in range(3)]
    kept = set().union(*rounds)
    assert len(kept) <= 2 and os.getpid() not in kept  # the session's 2 workers ran every round
    outside = [{r[2] for r in run_tasks(tasks.statistic, [(s, 100) for s in range(8)], where)} for _ in range(2)]
    assert not outside[0] & kept and not outside[0] & outside[1]  # closed at its end; new workers each time


def test_an_execution_says_where_it_runs():
    assert [e.describe() for e in BACKENDS] == [
        "2 threads",
        "2 local worker processes",
        "a Dask local cluster of 2 worker processes",
    ]
    assert Execution("dask", 1, "tcp://10.0.0.5:8786").describe() == "the Dask cluster at tcp://10.0.0.5:8786"
    assert Execution("threads", 1).describe() == "1 thread"


def test_a_task_not_safe_in_threads_runs_on_worker_processes_where_threads_were_chosen():
    log = Feedback()
    pids = run_tasks(tasks.pid_after, [(0.0,)] * 2, Execution("threads", 2), log, "libraries", thread_safe=False)
    assert os.getpid() not in pids
    assert any("libraries: not safe in threads, run on local worker processes" in m for m in log.messages)
    assert run_tasks(tasks.pid_after, [(0.0,)], Execution("threads", 1)) == [os.getpid()]


@pytest.mark.parametrize("where", BACKENDS[:2], ids=lambda e: e.backend)
def test_a_cancel_stops_the_pending_tasks(where, tmp_path):
    stop = Feedback(cancel_at=1.0)  # cancelled once the first task has finished
    with pytest.raises(CancelledError):
        run_tasks(tasks.slow_marker, [(str(tmp_path), k, 0.3) for k in range(20)], where, stop)
    time.sleep(1.0)
    # only the tasks a worker had started ran: the first two (finishing together) and the 2 running then (a
    # worker process is sent a task only when it waits for one); the 16 or more others never ran
    assert len(os.listdir(tmp_path)) <= 2 + 2


class _StopAtFirstStage(Feedback):
    """Cancels once a task has finished its first stage (a file <k>.0 in `folder`); keeps the files there then."""

    def __init__(self, folder):
        super().__init__()
        self.folder, self.seen = folder, None

    def isCanceled(self):
        if self.seen is None and any(n.endswith(".0") for n in os.listdir(self.folder)):
            self.seen = set(os.listdir(self.folder))
        return self.seen is not None


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_a_cancel_reaches_into_the_running_tasks(where, tmp_path):
    stop = _StopAtFirstStage(str(tmp_path))
    with pytest.raises(CancelledError):  # 4 tasks of 100 stages of 0.05 s, 2 at a time
        run_tasks(tasks.staged, [(str(tmp_path), k, 100, 0.05) for k in range(4)], where, stop)
    after = set(os.listdir(tmp_path))
    time.sleep(0.5)
    assert set(os.listdir(tmp_path)) == after  # nothing runs on after the cancel
    started = {n for n in after if n.startswith("pid-")}
    assert 1 <= len(started) <= 2  # the pending tasks never started
    stages = {k: sum(n.startswith(f"{k}.") for n in after) for k in range(4)}
    # each running task stopped at its next look at the token: within a stage of the cancel for threads and
    # processes (a POLL of 0.1 s is 2 stages), within DASK_CHECK (1 s, 20 stages) on Dask; never at its end
    late = 2 + 2 + (dask_backend.DASK_CHECK / 0.05 if where.backend == "dask" else 0)
    for k, count in stages.items():
        assert count < 100 and count <= sum(n.startswith(f"{k}.") for n in stop.seen) + late, (k, count)


@pytest.mark.parametrize("where", BACKENDS, ids=lambda e: e.backend)
def test_a_task_error_is_raised_as_it_is(where):
    with pytest.raises(InputError, match="task 2 refuses"):
        run_tasks(tasks.refuse, [(k,) for k in range(6)], where)


def test_dask_reruns_the_task_of_a_killed_worker(tmp_path):
    out = run_tasks(tasks.die_once, [(str(tmp_path), k) for k in range(6)], Execution("dask", 2))
    assert (tmp_path / "died-1").exists()  # the worker did die
    assert out == [k * k for k in range(6)]  # and the run completed with every result


def _kill_first_worker(folder):
    """A thread that kills (SIGKILL, as the OOM killer) the worker process of the first task that leaves its pid
    file in `folder`; returns the pid in the list it fills."""
    killed = []

    def first():
        return next(filter(None, (pid_in(f) for f in sorted(pathlib.Path(folder).glob("pid-*")))), None)

    def kill():
        killed.append(first())
        os.kill(killed[0], signal.SIGKILL)

    when(lambda: first() is not None, kill, timeout=60)
    return killed


@pytest.mark.parametrize("rounds", [1, 3], ids=["one round", "the third round of a session"])
def test_a_killed_worker_process_cuts_its_round_short_and_fails_the_step(tmp_path, rounds):
    where = Execution("processes", 2)
    # each task carries 8 MiB, more than a pipe holds (64 KiB): when the worker dies, the next tasks are being
    # written to the workers (concurrent.futures' pool then hung for ever, CPython 3.11, gh-94777)
    blob = bytes(8 * 2**20)
    folders = [tmp_path / f"round-{r}" for r in range(rounds)]
    with pytest.raises(ExecutionError) as failed:
        with execution.session(where):
            for r, folder in enumerate(folders):
                folder.mkdir()
                last = r == rounds - 1
                killed = _kill_first_worker(str(folder)) if last else None
                run_tasks(
                    tasks.staged,
                    [(str(folder), k, 200 if last else 1, 0.05, blob) for k in range(6)],
                    where,
                    what="the test",
                )
    assert killed and str(failed.value).startswith(f"the test: worker process {killed[0]} died (killed by SIGKILL")
    assert "fewer workers" in str(failed.value)  # and what to do
    # cut short, not waited out: no task of the last round ran its 200 stages (10 s uncancelled) to the end
    assert not list(folders[-1].glob("*.199"))
    assert worker_processes(os.getpid()) == []  # the other worker stopped with the round, none is left behind


def test_a_scheduler_that_does_not_answer_is_a_clear_error():
    start = time.monotonic()
    with pytest.raises(ExecutionError, match="no Dask scheduler answers at tcp://127.0.0.1:9 within 3 s"):
        run_tasks(tasks.refuse, [(0,)], Execution("dask", 2, address="tcp://127.0.0.1:9", connect_timeout=3))
    assert time.monotonic() - start < 30  # the bound: an error, not a hang


@pytest.mark.parametrize("host", ["/usr/bin/qgis", "/root/.pyenv/shims/python3"])
def test_worker_processes_start_this_python_when_the_host_is_not_it(monkeypatch, host):
    # QGIS reports its binary, or (embedded Python) the first python3 on PATH, maybe another installation's
    monkeypatch.setattr(sys, "executable", host)
    exe = task_runtime.python_executable()
    assert exe.startswith(sys.exec_prefix + os.sep) and os.path.basename(exe).startswith("python")  # this venv's
    out = run_tasks(tasks.statistic, [(1, 10), (2, 10)], Execution("processes", 2))
    assert [r[0] for r in out] == [1, 2]


@pytest.mark.parametrize(
    "bad, message",
    [
        (Execution("cluster"), "must be one of threads, processes, dask"),
        (Execution("threads", 0), "at least one worker"),
        (Execution("threads", address="tcp://h:8786"), "is for the dask execution"),
    ],
)
def test_settings_no_backend_can_use_are_refused(bad, message):
    with pytest.raises(InputError, match=message):
        bad.check()


@pytest.mark.parametrize(
    "address",
    [
        "htp:/nonsense::99",
        "localhost",
        "ucx://10.0.0.5:8786",
        "tcp://10.0.0.5",
        "tcp://10.0.0.5:99999",
        "tcp://10.0.0.5:8786/path",
    ],
)
def test_a_malformed_scheduler_address_is_refused_before_connecting(address):
    with pytest.raises(
        InputError,
        match=r"give the scheduler's address as tcp://host:port .* or tls://host:port, "
        r"or leave it empty for a local cluster",
    ) as refused:
        Execution("dask", 2, address).check()
    assert repr(address) in str(refused.value)  # the address as given


@pytest.mark.parametrize(
    "address", ["tcp://10.0.0.5:8786", "tls://scheduler.example.org:8786", "localhost:8786", "tcp://[::1]:8786"]
)
def test_a_scheduler_address_of_the_expected_form_is_accepted(address):
    assert Execution("dask", 2, address).check().address == address


def test_more_workers_than_the_machine_takes_are_capped_with_a_warning():
    limit = task_runtime.WORKERS_PER_CORE * os.cpu_count()
    many = Execution("threads", 1000 * limit)
    log = Feedback()
    with execution.session(many):
        for _ in range(2):
            assert run_tasks(tasks.refuse, [(0,), (1,)], many, log) == [0, 1]
    warning = f"{1000 * limit} workers asked for, {limit} used: at most {task_runtime.WORKERS_PER_CORE} per core"
    assert [m for m in log.messages if m.startswith(warning)] == log.messages[:1]  # said once, first
    assert log.messages[1] == f"the tiles: 2 tasks on {limit} threads"
    assert Execution("processes", 1000 * limit).describe() == f"{limit} local worker processes"
    assert Execution("dask", 1000 * limit).describe() == f"a Dask local cluster of {limit} worker processes"
    assert Execution("dask", 1000 * limit, "tcp://10.0.0.5:8786").capped() is None  # a remote cluster's own


def test_a_thousand_workers_start_no_more_processes_than_the_cap(monkeypatch):
    """The issue's WORKERS=1000 (it exhausted the machine's memory): the local pool runs twice as many tasks as
    the cap in at most the cap's processes, and the Dask local cluster is asked for the cap (its constructor is
    recorded, not run: the cap's worker processes are the pool's test)."""
    import distributed

    limit = task_runtime.worker_limit()
    log = Feedback()
    pids = run_tasks(tasks.pid_after, [(0.3,)] * (2 * limit), Execution("processes", 1000), log)
    assert 1 < len(set(pids)) <= limit and os.getpid() not in pids
    assert log.messages[0].startswith(f"1000 workers asked for, {limit} used: at most")
    asked = {}

    class RecordedError(Exception):
        pass

    def record(**settings):
        asked.update(settings)
        raise RecordedError

    monkeypatch.setattr(distributed, "LocalCluster", record)
    with pytest.raises(RecordedError):
        run_tasks(tasks.pid_after, [(0.0,)], Execution("dask", 1000))
    assert asked["n_workers"] == limit and asked["threads_per_worker"] == 1 and asked["processes"]


def test_a_local_cluster_starts_without_its_known_warnings(recwarn):
    with execution.session(BACKENDS[2]):
        actions = run_tasks(tasks.warning_action, [(m, c.__name__) for m, c in dask_backend.DASK_NOISE], BACKENDS[2])
    assert actions == ["ignore", "ignore"]  # the workers' filters (UserWarning is shown by default)
    noise = [str(w.message) for w in recwarn if any(str(w.message).startswith(m) for m, _ in dask_backend.DASK_NOISE)]
    assert noise == []  # nor does this process show them (recwarn records every warning)
