"""The dask execution of run_tasks (execution.py): Dask distributed, on a LocalCluster of single-threaded worker
processes or on the cluster whose scheduler listens at an address.

The cluster as run_tasks sees it:
- **Workers.** Before a round's tasks are submitted the scheduler is asked for its workers. With none, the round
  waits up to `Execution.worker_wait` s (cancellable) for one to join, then fails with ExecutionError saying how
  many are connected and how to start one. The log names the workers once (`the Dask cluster at ...: 2 workers`),
  each worker that leaves (its running tiles run again on the others: distributed's allowed-failures) or joins,
  and, at the end of each round, the tiles each worker ran.
- **Every worker checked.** Each worker, at connection and as it joins, runs worker_report.report (Client.run; the
  module travels by value, so a worker without pushbroom answers too). A worker that misses pushbroom, numba or
  GDAL, or runs another Pushbroom or Python, fails the round before its tasks run, naming its address, host and
  what it misses; one without CNES libsgm is a warning (dense matching's tiles fail there).
- **No single copy of shared data.** What all of a round's tasks share (a step's job: models, images,
  parameters) is the result of a task of its own (`_held`), not scattered data: the scheduler keeps its
  definition, so when the last worker holding it dies it is computed again on another. Scattered data lives only
  on workers, and Dask's active memory manager (on by default, every 2 s) keeps one replica of it: when that
  worker died, the tasks waiting for it were cancelled (the issue of the cluster test, distributed 2022.12).
  Dask places a task beside its data: a round of up to twice the cluster's threads starts on the worker that holds
  the job and spreads by work stealing; a larger round is queued on the scheduler and spread as workers free up.
- **Every worker lost.** When the scheduler has had no worker for `worker_wait` s during a round, the round fails
  with ExecutionError: the step, the tiles finished, and that nothing was stored. A task the cluster cancelled (its
  data lost, the scheduler gone), a task that killed its workers in turn (distributed's KilledWorker) and a task
  that cannot import a module on its worker are ExecutionErrors in the same words; other task errors are raised
  as the task raised them.
- **Cancel.** The cancel token of a round is a distributed Event named after it (`_DaskFlag`); a task asks the
  scheduler at most every DASK_CHECK s.
- **Quiet.** The warnings Dask gives on every start (DASK_NOISE: tornado's deprecation of make_current, a loaded
  machine's "scratch directories") are filtered in this process, and in the local cluster's worker processes;
  the local cluster is closed and collected at the end of its step, so that qgis_process, which ends without
  Python's exit handlers, leaves no semaphore to the resource tracker.

Failure modes: ExecutionError (no scheduler answers within `connect_timeout` s, or one stops answering for ANSWER
s; no worker; every worker lost; a worker that cannot run Pushbroom; Dask distributed not installed). The workers
are asked for at most every DASK_CHECK s. Reference: distributed's documentation,
"Data Locality", "Active Memory Manager" and "Resilience" (a lost key is recomputed from its task; scattered data
is not)."""

from __future__ import annotations

import collections
import contextlib
import gc
import platform
import re
import time
import uuid
import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from ..version import VERSION
from . import progress, worker_report
from .errors import ExecutionError
from .task_runtime import GRACE, POLL, Execution, in_worker, starting_workers, use_python_for_workers

if TYPE_CHECKING:
    from distributed import Client, Future, LocalCluster

    from .progress import Feedback

T = TypeVar("T")

#: s a task on Dask waits between two looks at the cancel token (each asks the scheduler)
DASK_CHECK = 1.0
#: warnings a Dask local cluster or client gives on every start (the start of the message, the category)
DASK_NOISE = (
    ("make_current is deprecated", DeprecationWarning),
    ("Creating scratch directories is taking a surprisingly long time", UserWarning),
)
#: s the scheduler (and a worker, for its check) has to answer a question before it counts as gone
ANSWER = 30.0
#: what nothing stored means to the user, in every message of a failed round
UNCHANGED = "nothing was stored: the block and the outputs are as they were"


def _quiet() -> None:
    """DASK_NOISE filtered in this process from now on (the client's event loop thread may warn at any time)."""
    for message, category in DASK_NOISE:
        warnings.filterwarnings("ignore", message=re.escape(message), category=category)


class _DaskFlag:
    """The cancel token of a Dask round: the distributed Event named `name`, asked at most every DASK_CHECK s
    (each look is a message to the scheduler); the name alone travels with the tasks."""

    def __init__(self, name: str):
        self.name, self.seen, self.at = name, False, -float("inf")

    def __reduce__(self) -> tuple[type[_DaskFlag], tuple[str]]:
        return _DaskFlag, (self.name,)

    def is_set(self) -> bool:
        if not self.seen and time.monotonic() - self.at >= DASK_CHECK:
            import distributed

            with contextlib.suppress(Exception):  # no answer: not cancelled (the task runs to its end)
                self.seen = bool(distributed.Event(self.name).is_set())
            self.at = time.monotonic()
        return self.seen


def _held(value: T) -> T:
    """A round's shared value, as the result of a task (module docstring)."""
    return value


def _in_dask_worker(function: Callable[..., T], args: Sequence[Any], token: _DaskFlag) -> tuple[str, T]:
    """(the worker's address, in_worker(function, args, token)): the task wrapper on Dask."""
    import distributed

    return distributed.get_worker().address, in_worker(function, args, token)


def _connect(address: str, timeout: float) -> Client:
    """A distributed Client of the scheduler at `address` (ExecutionError where none answers within `timeout` s)."""
    import distributed

    try:
        return distributed.Client(address, timeout=f"{timeout}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise ExecutionError(
            f"no Dask scheduler answers at {address} within {timeout:g} s ({exc}): start one "
            "(`dask scheduler`) and its workers (`dask worker <address>`), or leave the address "
            "empty for a local cluster"
        ) from None
    except Exception as exc:  # e.g. tls:// without Dask's TLS configuration
        raise ExecutionError(
            f"cannot connect to the Dask scheduler at {address} ({exc}): check the address, and "
            "for tls:// Dask's TLS configuration (distributed.comm.tls)"
        ) from None


def _reports(client: Client, addresses: list[str]) -> dict[str, Any]:
    """{address: worker_report.report() of that worker, or the exception that kept it from answering}."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(worker_report)  # a worker without pushbroom must still unpickle it
    return client.run(worker_report.report, workers=addresses, on_error="return", callback_timeout=ANSWER)


def worker_reports(address: str, timeout: float = 30.0) -> dict[str, Any]:
    """{worker address: worker_report.report(), or the exception it answered with} of every worker of the cluster
    at `address` (worker_check.py, the command line)."""
    _quiet()
    client = _connect(address, timeout)
    try:
        return _reports(client, list(client.scheduler_info()["workers"]))
    finally:
        client.close()


class DaskBackend:
    """run_tasks' backend on Dask distributed (module docstring; execution.py describes the backends' methods)."""

    def __init__(self, execution: Execution):
        try:
            import distributed
        except ImportError as exc:
            raise ExecutionError(
                "the dask execution needs Dask distributed (python3-distributed), which is not "
                "installed: run `make setup`, or choose threads or processes"
            ) from exc
        _quiet()
        self.execution, self.note = execution, execution.capped()
        self.cluster: LocalCluster | None = None
        self.where = f"the Dask cluster at {execution.address}" if execution.address else "the Dask local cluster"
        self.token, self.what = _DaskFlag(""), "the tiles"
        self.feedback: Feedback | None = None
        self.workers: dict[str, str] = {}  # address -> host, as last seen
        self.checked: set[str] = set()  # addresses whose check passed
        self.named = False  # the workers were named in the log
        self.tally: collections.Counter[str] = collections.Counter()
        self.total = self.finished = 0
        self.alone_since: float | None = None  # when the scheduler was last seen with no worker
        self.looked = -float("inf")  # when the scheduler was last asked for its workers
        if execution.address:
            self.client = _connect(execution.address, execution.connect_timeout)
            return
        use_python_for_workers()
        quiet = ",".join(f"ignore:{message}:{category.__name__}" for message, category in DASK_NOISE)
        with starting_workers({"PYTHONWARNINGS": quiet}):
            # no dashboard; the scheduler's HTTP server (health, metrics) on a free local port, not on 8787, which
            # another cluster may hold ("Port 8787 is already in use")
            self.cluster = distributed.LocalCluster(
                n_workers=execution.used_workers(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                silence_logs=40,
            )  # logging.ERROR
            try:
                self.client = distributed.Client(self.cluster, set_as_default=False)
            except BaseException:
                self.close(True)
                raise

    # ---- the workers

    def _ask(self, call: Callable[..., Any], **kwargs: Any) -> Any:
        """`call(**kwargs)` on the client's loop, answered within ANSWER s; ExecutionError where the scheduler does
        not answer (it died, or the network is gone)."""
        try:
            return self.client.sync(call, callback_timeout=ANSWER, **kwargs)
        except Exception as exc:
            raise self._failure(
                f"the Dask scheduler of {self.where} stopped answering ({type(exc).__name__}: {exc})"
            ) from None

    def _present(self) -> dict[str, str]:
        """{address: host} of the scheduler's workers, as the scheduler answers now."""
        # distributed types Client.scheduler as optional: it is None only before the client has connected
        info = self._ask(self.client.scheduler.identity)  # type: ignore[union-attr]
        self.looked = time.monotonic()
        return {a: str(w.get("host", "")) or a for a, w in info["workers"].items()}

    def _label(self, address: str) -> str:
        host = self.workers.get(address, "")
        return f"{address} ({host})" if host and host not in address else address

    def _start_one(self) -> str:
        return (
            f"start one on a host that sees the same files, `python3 -m distributed.cli.dask_worker "
            f"{self.execution.address or '<address>'} --nthreads 1` (README, Scaling out), or raise the wait "
            "(DASK_WAIT)"
        )

    def _wait_for_workers(self) -> dict[str, str]:
        """The scheduler's workers (_present) once it has one; ExecutionError after `worker_wait` s without one."""
        wait = float(self.execution.worker_wait)
        deadline = time.monotonic() + wait
        told = False
        while not (present := self._present()):
            if time.monotonic() >= deadline:
                raise self._failure(
                    f"no worker joined {self.where} within {wait:g} s (0 workers connected): {self._start_one()}"
                )
            if not told:
                progress.warn(self.feedback, f"{self.where} has no worker: waiting up to {wait:g} s for one")
                told = True
            while time.monotonic() - self.looked < DASK_CHECK:
                self._idle()
        self.alone_since = None
        return present

    def _idle(self) -> None:
        if self.execution.host_events is not None:
            self.execution.host_events()
        progress.check(self.feedback)
        time.sleep(POLL)

    def _check(self, addresses: list[str], present: dict[str, str]) -> None:
        """ExecutionError where a worker of `addresses` (among the scheduler's `present` workers) cannot run
        Pushbroom's tasks (module docstring); the others are checked for good."""
        try:
            reports = _reports(self.client, addresses)
        except Exception as exc:  # the scheduler died, or a worker does not answer within ANSWER s
            raise self._failure(
                f"the workers of {self.where} could not be checked ({type(exc).__name__}: {exc})"
            ) from None
        failing: list[str] = []
        dense: list[str] = []
        for address, seen in sorted(reports.items()):
            if isinstance(seen, BaseException) and address not in present:
                continue  # a worker that left before it answered
            said = worker_report.problems(seen, VERSION, platform.python_version())
            if said:
                failing.append(f"{worker_report.describe(address, seen)}: {'; '.join(said)}")
                continue
            if worker_report.dense_missing(seen):
                dense.append(f"{address} on {seen['host']}")
            self.checked.add(address)
        if failing:
            raise self._failure(
                f"{len(failing)} of {len(present)} workers of {self.where} cannot run Pushbroom's "
                f"tasks: {'; '.join(failing)}. `python3 -m pushbroom.algorithms.worker_check "
                f"{self.execution.address or '<address>'}` checks every worker"
            )
        if dense:
            progress.warn(
                self.feedback,
                f"{len(dense)} worker{'s' * (len(dense) != 1)} of {self.where} lack CNES "
                f"libsgm (c_libsgm): {', '.join(dense)}; dense matching's tiles fail there "
                "(install the plugin's wheel with its `dense` extra)",
            )

    def _changes(self, present: dict[str, str]) -> list[str]:
        """Log the workers that left or joined since the last look; the joined ones."""
        log = progress.ensure(self.feedback)
        n = len(present)
        for address in sorted(self.workers.keys() - present.keys()):
            after = (
                f"its running tiles run again on another ({n} worker{'s' * (n != 1)} left)"
                if n
                else "no worker is left"
            )
            log.pushInfo(f"{self.what}: worker {self._label(address)} left {self.where}; {after}")
        joined = sorted(present.keys() - self.workers.keys())
        self.workers = present
        for address in joined:
            log.pushInfo(f"{self.what}: worker {self._label(address)} joined {self.where} ({n} workers)")
        return joined

    def _watch(self) -> None:
        """At most every DASK_CHECK s: log the workers that left or joined, check the new ones; ExecutionError once
        the scheduler has had no worker for `worker_wait` s."""
        if time.monotonic() - self.looked < DASK_CHECK:
            return
        present = self._present()
        new = [a for a in self._changes(present) if a not in self.checked]
        if new:
            self._check(new, present)
        if present:
            self.alone_since = None
            return
        wait = float(self.execution.worker_wait)
        if self.alone_since is None:
            self.alone_since = time.monotonic()
            progress.warn(
                self.feedback,
                f"{self.what}: every worker of {self.where} is lost: waiting up to {wait:g} s for one to come back",
            )
        elif time.monotonic() - self.alone_since > wait:
            raise self._failure(
                f"every worker of {self.where} was lost, and none came back within {wait:g} s (0 "
                f"workers connected): {self._start_one()}"
            )

    def _failure(self, text: str) -> ExecutionError:
        """The round's failure: `text`, the tasks finished, and that nothing was stored."""
        return ExecutionError(
            f"{self.what}: {text}; {self.finished} of {self.total} task{'s' * (self.total != 1)} finished, {UNCHANGED}"
        )

    # ---- run_tasks' backend

    def begin(self, what: str, feedback: Feedback | None, total: int) -> None:
        self.what, self.feedback, self.total, self.finished = what, feedback, total, 0
        self.tally = collections.Counter()
        self.token = _DaskFlag(f"pushbroom-cancel-{uuid.uuid4().hex}")
        present = self._wait_for_workers()
        if not self.named:
            self.named, self.workers = True, present
            progress.ensure(feedback).pushInfo(
                f"{self.where}: {len(present)} worker{'s' * (len(present) != 1)} "
                f"({', '.join(self._label(a) for a in sorted(present))})"
            )
        else:
            self._changes(present)
        unchecked = [a for a in present if a not in self.checked]
        if unchecked:
            self._check(unchecked, present)

    def prepare(self, tasks: list[Sequence[Any]]) -> list[Sequence[Any]]:
        """The tasks as submitted: each object that every task passes at the same place (a step's job: its
        models, images and parameters) made the result of a task of its own and passed as its future, which the
        workers resolve: the scheduler holds it once, not once per task, and computes it again where it is lost
        (module docstring)."""
        shared: dict[int, Future] = {}
        if len(tasks) > 1:
            for i, value in enumerate(tasks[0]):
                if isinstance(value, (str, bytes, int, float, bool, type(None))) or callable(value):
                    continue  # small, or sent by reference (a strategy's class, write_part)
                if all(len(t) > i and t[i] is value for t in tasks):
                    with warnings.catch_warnings():  # Dask's advice to scatter it instead (module docstring)
                        warnings.filterwarnings("ignore", message="Large object of size", category=UserWarning)
                        shared[i] = self.client.submit(
                            _held, value, pure=False, key=f"pushbroom-job-{uuid.uuid4().hex}"
                        )
        return [tuple(shared.get(i, a) for i, a in enumerate(t)) for t in tasks] if shared else tasks

    def submit(self, function: Callable[..., Any], args: Sequence[Any]) -> Future:
        # pure=False: a task is run, not looked up (two runs of the same tile may write different files). The
        # arguments go as a list: Dask takes a tuple whose first item is callable for a task of its own, and would
        # call it (a matching strategy's class first, `RegionGrowing(job, ...)`); in a list it finds the shared
        # job's future all the same (prepare)
        return self.client.submit(_in_dask_worker, function, list(args), self.token, pure=False)

    def done(self, futures: set[Future]) -> set[Future]:
        self._watch()
        done = {f for f in futures if f.done()}
        if not done:
            time.sleep(POLL)
        return done

    def result(self, future: Future) -> Any:
        """The task's result; the task's own exception as it raised it; ExecutionError in our words where the
        cluster lost or refused it (module docstring). A result whose worker died before it was fetched is
        computed again: waited for with the cluster watched and the cancel button asked."""
        import distributed

        while True:
            try:
                address, value = future.result(timeout=DASK_CHECK)
                break
            except Exception as exc:
                if future.status == "error":
                    if isinstance(exc, distributed.KilledWorker):
                        raise self._failure(
                            f"a task's workers died while running it, one after another ({exc}): it "
                            "may need more memory than a worker has; run again with smaller tiles"
                        ) from None
                    if isinstance(exc, ImportError):
                        raise self._failure(
                            f"a worker of {self.where} cannot import what a task needs ({exc}): "
                            "install the plugin's wheel with its extras there (README, Scaling out)"
                        ) from None
                    raise
                if future.status == "cancelled":
                    raise self._failure(
                        f"{self.where} cancelled a task (the scheduler lost its data, or restarted)"
                    ) from None
                if not isinstance(exc, TimeoutError):
                    raise self._failure(
                        f"the result of a task could not be fetched from {self.where} ({type(exc).__name__}: {exc})"
                    ) from None
                self._watch()
                self._idle()
        self.tally[address] += 1
        self.finished += 1
        return value

    def end(self) -> str | None:
        """The round's last look at the cluster (a worker that left or joined since the last look is named; the
        next round checks a new one) and its line for the log: the tasks each worker ran."""
        self._changes(self._present())
        return f"{self.what}: tasks per worker: " + ", ".join(
            f"{self._label(a)} {n}" for a, n in sorted(self.tally.items())
        )

    def cancel(self, futures: Iterable[Future]) -> None:
        """Set the round's Event (it stays on the scheduler, a name) and wait until the round's `futures` are
        done, GRACE s at most (closing a local cluster would kill the tasks wherever they are). The futures are let go
        with the round: the scheduler then drops the tasks that have not started, with no call that a dead
        scheduler could hold up."""
        if not self.token.name or not self.workers:  # no round began, or nothing runs: nothing to wait for
            return
        with contextlib.suppress(Exception):
            self.client.sync(
                self.client.scheduler.event_set,  # type: ignore[union-attr]  # as in _present
                name=self.token.name,
                callback_timeout=GRACE,
            )
        deadline = time.monotonic() + GRACE
        while not all(f.done() for f in futures) and time.monotonic() < deadline:
            time.sleep(POLL)

    def close(self, cancel: bool) -> None:
        with contextlib.suppress(Exception):
            self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()
            self.cluster = None
            gc.collect()  # the nannies' queues, with their semaphores
