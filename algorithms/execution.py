"""Independent tile tasks on threads, local worker processes or Dask distributed.

A step cuts its work into tasks that do not depend on one another (one per tile): a module-level
function and small arguments (a tile description, file paths, parameters) that writes its large
results to files and returns a small summary (a path, counts). `run_tasks` submits them to the
backend the user chose and collects the summaries, reporting progress over all of them and
cancelling the pending ones when the user cancels. Nothing large travels through the scheduler, so a
task runs the same on a thread, in another process or on another machine, and the results do not
depend on the backend or on the number of workers (they are returned in the order of the tasks).

Backends (`Execution.backend`):
- "threads": a thread pool in this process (numba kernels release the GIL); the default;
- "processes": local worker processes started by `spawn` (_Processes: one pipe per worker, one task at a time);
- "dask": Dask distributed, on a LocalCluster of `workers` single-threaded worker processes, or on the
  cluster whose scheduler listens at `address` (tcp://host:port or tls://host:port; every worker must see
  the same files under the same paths and import pushbroom).
Threads, local processes and a local cluster use at most task_runtime.WORKERS_PER_CORE workers per core of this machine:
more only share the cores and multiply the memory (each holds a tile); run_tasks warns when it uses fewer
than asked.

Worker processes start with this Python, its environment and SIGINT blocked (task_runtime.py); a step that runs
several rounds of tasks keeps its workers across them (`session`).

A dead worker. Dask reruns the task of a worker that dies on another worker (distributed's allowed-failures;
dask_backend.py says what a cluster without workers, or whose workers cannot run Pushbroom, does).
A local worker process that dies (the OOM killer, kill -9) fails the round as soon as it is seen (within POLL
s; the other running tasks are then cancelled, below) with an ExecutionError naming its pid and what ended it.
The local pool is this module's own, not concurrent.futures' ProcessPoolExecutor: on CPython 3.11 that one
hangs for ever when a worker dies while the feeder thread of its shared call queue writes a task into the pipe
(its shut-down joins the feeder, which waits for a reader that is gone: gh-94777), and a step's tasks carry
its job (images, models), so that pipe is nearly always being written. Here every worker has a pipe whose
other end only it holds, and is sent a task only when it has said it waits for one: a write to a dead worker
fails (EPIPE), a read from it ends (EOF), and the workers' sentinels are watched with the pipes, so no wait
outlives a worker.

Cancelling reaches into the running tasks. When the user cancels, or a task fails, run_tasks sets the round's
cancel token, which tasks ask between their stages (`cancelled`, `check_cancel`, through in_worker): the tile
functions of the steps stop there with CancelledError, so a step ends within a stage of a tile. The token is a
threading.Event for threads, one byte of shared memory for local processes, and a Dask Event for dask
(dask_backend.py). Pending tasks are cancelled; running ones are given GRACE s to
stop, after which local worker processes are killed (their temporary files go with the step's work folder, or
with the next write into their folder: atomic's leftovers); threads cannot be killed and are waited for.
qgis_process cancels the feedback on Ctrl+C only when its Qt event loop runs, which it does not while an
algorithm runs: `Execution.host_events` (the plugin's execution_choice sets it) is called while run_tasks waits.

Failure modes: InputError for unusable settings (an unknown backend, no worker, a malformed scheduler
address); ExecutionError when a local worker process dies, when no Python interpreter can be found, or for a Dask
cluster's failures (dask_backend.py); a task's own exception is raised as it is (other than the engine's own
errors, with the worker's traceback as a note); CancelledError when cancelled. The design follows the cluster
abstraction of CNES CARS (create tasks, start them, iterate over the futures as they complete).

The local pool has no semaphore (pipes and one byte of shared memory)."""

from __future__ import annotations

import collections
import concurrent.futures as cf
import contextlib
import dataclasses
import multiprocessing
import multiprocessing.connection
import os
import pickle
import signal
import threading
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Sequence
from multiprocessing.reduction import ForkingPickler
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

from . import progress
from .errors import CancelledError, ExecutionError, PushbroomError
from .task_runtime import (
    GRACE,
    POLL,
    WORKER_ENVIRONMENT,
    Execution,
    in_worker,
    run_with_token,
    starting_workers,
    use_python_for_workers,
)

if TYPE_CHECKING:
    import ctypes
    from multiprocessing.connection import Connection
    from multiprocessing.context import SpawnContext

    from .progress import Feedback

T = TypeVar("T")
#: a task as a worker process receives it: the function and its arguments
_Task = tuple[Callable[..., Any], Sequence[Any]]


class _SharedFlag:
    """The cancel token of local worker processes: one byte of shared memory (set: 1)."""

    def __init__(self, value: ctypes.c_byte):
        self.value = value  # multiprocessing RawValue("b")

    def is_set(self) -> bool:
        return self.value.value != 0


# ---- the backends: begin(what, feedback, total), prepare(tasks) -> tasks, submit(function, args) -> future,
# done(futures) -> the finished, result(future), end() -> a line for the log or None, cancel(futures): set the
# token and give the running tasks GRACE s to stop, close(cancel); `note`: the warning run_tasks gives once
# (Execution.capped). dask_backend.DaskBackend is the dask one.


class Backend(Protocol):
    """What run_tasks asks of a backend (above); a future is the backend's own (concurrent.futures' or Dask's)."""

    note: str | None

    def begin(self, what: str, feedback: Feedback | None, total: int) -> None: ...

    def prepare(self, tasks: list[Sequence[Any]]) -> list[Sequence[Any]]: ...

    def submit(self, function: Callable[..., Any], args: Sequence[Any]) -> Any: ...

    def done(self, futures: set[Any]) -> set[Any]: ...

    def result(self, future: Any) -> Any: ...

    def end(self) -> str | None: ...

    def cancel(self, futures: Iterable[Any]) -> None: ...

    def close(self, cancel: bool) -> None: ...


class _Local:
    """What the backends of this machine share: tasks submitted as they are, results as the futures hold them."""

    note: str | None = None

    def prepare(self, tasks: list[Sequence[Any]]) -> list[Sequence[Any]]:
        """The tasks as they are submitted (pickled per task for worker processes)."""
        return tasks

    def result(self, future: cf.Future[T]) -> T:
        return future.result()

    def end(self) -> str | None:
        return None


class _Threads(_Local):
    """threads: concurrent.futures' thread pool; a threading.Event per round as the cancel token."""

    def __init__(self, execution: Execution):
        self.note = execution.capped()
        self.pool = cf.ThreadPoolExecutor(execution.used_workers())
        self.token = threading.Event()

    def begin(self, what: str, feedback: Feedback | None, total: int) -> None:
        self.token = threading.Event()

    def submit(self, function: Callable[..., T], args: Sequence[Any]) -> cf.Future[T]:
        return self.pool.submit(run_with_token, function, args, self.token)

    def done(self, futures: set[cf.Future[Any]]) -> set[cf.Future[Any]]:
        return cf.wait(futures, timeout=POLL, return_when=cf.FIRST_COMPLETED)[0]

    def cancel(self, futures: Iterable[cf.Future[Any]]) -> None:
        self.token.set()  # close waits for the running ones (a thread cannot be stopped)
        for future in futures:
            future.cancel()

    def close(self, cancel: bool) -> None:
        self.pool.shutdown(wait=True, cancel_futures=cancel)


def _serve(conn: Connection, flag: ctypes.c_byte) -> None:
    """A local worker process (_Processes): say it waits (None), run each task it is sent and send back
    (True, result) or (False, exception); end at None, or when the step's process has gone (EOF)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    token, reply = _SharedFlag(flag), None
    while True:
        try:
            try:
                data = ForkingPickler.dumps(reply)
            except Exception as exc:  # a result that cannot be pickled
                data = ForkingPickler.dumps(
                    (
                        False,
                        ExecutionError(
                            f"the result of a task could not be sent back from worker process {os.getpid()}: {exc}"
                        ),
                    )
                )
            conn.send_bytes(data)
            message = conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            task: _Task | None = pickle.loads(message)
            if task is None:
                return
            reply = (True, in_worker(*task, token))
        except BaseException as exc:  # SIGINT is ignored: a task's exception, or SystemExit
            reply = (False, _portable(exc))


def _portable(exc: BaseException) -> Exception:
    """A task's exception as the step's process can receive it: itself (with the worker's traceback as a note,
    other than the engine's own errors), or an ExecutionError with its text where it cannot be pickled."""
    if not isinstance(exc, Exception):
        return ExecutionError(f"a task ended its worker process {os.getpid()} with {type(exc).__name__}: {exc}")
    if not isinstance(exc, PushbroomError):
        exc.add_note(f"in worker process {os.getpid()}:\n" + "".join(traceback.format_exception(exc)))
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return ExecutionError(f"a task failed in worker process {os.getpid()} with {type(exc).__name__}: {exc}")


class _Worker:
    """A local worker process, the step's end of its pipe, the future of its task (None: no task) and whether
    it waits for one."""

    def __init__(self, context: SpawnContext, flag: ctypes.c_byte):
        conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, flag), name="pushbroom worker", daemon=True)
        with starting_workers(WORKER_ENVIRONMENT):
            self.process.start()
        child.close()  # its end is the worker's alone: its death closes the pipe
        self.conn: Connection = conn
        self.task: cf.Future[Any] | None = None
        self.waits = False


class _Processes(_Local):
    """processes: local worker processes over pipes (module docstring); started as the tasks need them."""

    def __init__(self, execution: Execution):
        use_python_for_workers()
        self.note = execution.capped()
        self.size = execution.used_workers()
        self.context = multiprocessing.get_context("spawn")
        self.flag = self.context.RawValue("b", 0)
        self.workers: list[_Worker] = []
        self.queue: collections.deque[tuple[cf.Future[Any], _Task]] = collections.deque()
        self.what = "the tiles"

    def begin(self, what: str, feedback: Feedback | None, total: int) -> None:
        self.what = what
        self.flag.value = 0

    def submit(self, function: Callable[..., T], args: Sequence[Any]) -> cf.Future[T]:
        future: cf.Future[T] = cf.Future()
        self.queue.append((future, (function, args)))
        return future

    def done(self, futures: set[cf.Future[Any]]) -> set[cf.Future[Any]]:
        self._dispatch()
        self._receive(POLL)
        self._dispatch()
        return {f for f in futures if f.done()}

    def cancel(self, futures: Iterable[cf.Future[Any]]) -> None:
        """Set the token; wait until the busy workers have stopped (or died), GRACE s at most."""
        self.flag.value = 1
        for future, _ in self.queue:
            future.cancel()
        self.queue.clear()
        deadline = time.monotonic() + GRACE
        while any(w.task is not None for w in self.workers) and time.monotonic() < deadline:
            with contextlib.suppress(ExecutionError):  # a worker that dies meanwhile has stopped
                self._receive(min(POLL, max(deadline - time.monotonic(), 0.0)))

    def _dispatch(self) -> None:
        """Send queued tasks to the waiting workers; start workers (up to `size`) for the others."""
        waiting = [w for w in self.workers if w.waits]
        starting = sum(1 for w in self.workers if not w.waits and w.task is None)
        for _ in range(min(self.size - len(self.workers), len(self.queue) - len(waiting) - starting)):
            self.workers.append(_Worker(self.context, self.flag))
        while waiting and self.queue:
            future, task = self.queue.popleft()
            if not future.set_running_or_notify_cancel():
                continue
            worker = waiting.pop()
            worker.task, worker.waits = future, False
            try:
                worker.conn.send(task)  # it reads as it waits: returns once the worker has it all
            except (EOFError, OSError):
                raise self._lost(worker) from None
            except Exception as exc:  # the task's arguments cannot be pickled (before a byte is sent)
                future.set_exception(exc)
                worker.task, worker.waits = None, True
                waiting.append(worker)

    def _receive(self, timeout: float) -> None:
        """Wait up to `timeout` s for a worker's message or death, and take what came (ExecutionError for a death)."""
        if not self.workers:
            time.sleep(timeout)
            return
        ready = multiprocessing.connection.wait(
            [w.conn for w in self.workers] + [w.process.sentinel for w in self.workers], timeout
        )
        for worker in [w for w in self.workers if w.conn in ready or w.process.sentinel in ready]:
            try:
                while worker.conn.poll():
                    message = worker.conn.recv()
                    future, worker.task, worker.waits = worker.task, None, True
                    if future is None:
                        continue  # the worker's first message: it waits
                    ok, value = message
                    if ok:
                        future.set_result(value)
                    else:
                        future.set_exception(value)
            except (EOFError, OSError):
                raise self._lost(worker) from None
            if worker.process.sentinel in ready:
                raise self._lost(worker)

    def _lost(self, worker: _Worker) -> ExecutionError:
        """ExecutionError for a worker process that died; it leaves the pool."""
        worker.process.join(1.0)
        self.workers.remove(worker)
        worker.conn.close()
        code = worker.process.exitcode
        if code is None or code >= 0:
            cause = f"exit code {code}" if code is not None else "its pipe closed"
        else:
            name = signal.Signals(-code).name if -code in signal.valid_signals() else f"signal {-code}"
            cause = f"killed by {name}" + (": out of memory, or killed by hand" if -code == signal.SIGKILL else "")
        return ExecutionError(
            f"{self.what}: worker process {worker.process.pid} died ({cause}) "
            f"{'with a task' if worker.task else 'between tasks'}: "
            "run again with fewer workers or smaller tiles, or choose the threads execution"
        )

    def close(self, cancel: bool) -> None:
        """Stop the workers: the waiting ones are told to end, the busy ones (their task did not stop within
        `cancel`'s GRACE s) killed; no wait outlives a worker."""
        for worker in self.workers:
            if worker.task is None:
                with contextlib.suppress(OSError):
                    worker.conn.send(None)
        deadline = time.monotonic() + 5.0
        for worker in self.workers:
            if worker.task is None:
                worker.process.join(max(deadline - time.monotonic(), 0.0))
            if worker.process.is_alive():
                worker.process.kill()
                worker.process.join(5.0)
            worker.conn.close()
        self.workers = []


def _backend(execution: Execution) -> Backend:
    if execution.backend == "dask":
        from .dask_backend import DaskBackend

        return DaskBackend(execution)
    local: dict[str, Callable[[Execution], Backend]] = {"threads": _Threads, "processes": _Processes}
    return local[execution.backend](execution)


_sessions: dict[tuple[int, Execution], Backend] = {}  # (thread, Execution) -> the backend a `session` keeps


@contextlib.contextmanager
def session(execution: Execution | None = None) -> Iterator[None]:
    """Keep the workers (the thread pool, the worker processes, or the Dask LocalCluster or client) of
    `execution` for every run_tasks of it on this thread inside the block, so that a step that runs several rounds
    of tasks starts its workers once; they are closed when the block ends."""
    execution = (execution or Execution()).check()
    key = (threading.get_ident(), execution)
    if key in _sessions:
        yield
        return
    _sessions[key] = backend = _backend(execution)
    failed = True
    try:
        yield
        failed = False
    finally:
        del _sessions[key]
        backend.close(cancel=failed)  # run_tasks has cancelled a failed round's tasks


def run_tasks(
    function: Callable[..., T],
    tasks: Iterable[Sequence[Any]],
    execution: Execution | None = None,
    feedback: Feedback | None = None,
    what: str = "the tiles",
    thread_safe: bool = True,
) -> list[T]:
    """Run `function(*args)` for each `args` of the list `tasks` on `execution` (Execution; default
    threads) and return the results in the order of `tasks`. Progress runs 0-100 % over the tasks;
    a cancel stops the pending tasks, asks the running ones to stop (`check_cancel`) and raises CancelledError;
    the first task to fail does the same to the others and its exception is raised (module docstring). A function
    that is not `thread_safe` (a library with module-level state) runs on local worker processes where threads were
    chosen, and the log says so."""
    execution = (execution or Execution()).check()
    if not thread_safe and execution.backend == "threads":
        execution = dataclasses.replace(execution, backend="processes")
        progress.ensure(feedback).pushInfo(f"{what}: not safe in threads, run on local worker processes")
    tasks = list(tasks)
    results: list[Any] = [None] * len(tasks)
    if not tasks:
        return results
    kept = _sessions.get((threading.get_ident(), execution))
    backend = kept or _backend(execution)
    progress.warn(feedback, backend.note)  # once per backend
    backend.note = None
    progress.ensure(feedback).pushInfo(f"{what}: {len(tasks)} task{'s' * (len(tasks) != 1)} on {execution.describe()}")
    futures: dict[Any, int] = {}
    failed = True
    try:
        backend.begin(what, feedback, len(tasks))
        submitted = backend.prepare(tasks)  # held to the round's end: on Dask it holds the shared job's future
        for k, args in enumerate(submitted):
            futures[backend.submit(function, args)] = k
        pending = set(futures)
        while pending:
            if execution.host_events is not None:
                execution.host_events()
            if feedback is not None and feedback.isCanceled():
                raise CancelledError("cancelled by the user")
            for future in backend.done(pending):
                pending.discard(future)
                # a finished task is let go at once: Dask then forgets its result and its arguments
                results[futures.pop(future)] = backend.result(future)
                progress.step(feedback, 100.0 * (len(tasks) - len(pending)) / len(tasks))
        failed = False
        line = backend.end()
        if line is not None:
            progress.ensure(feedback).pushInfo(line)
    finally:
        if failed:
            backend.cancel(futures)  # the pending ones are dropped, the running ones stop at the token
        if kept is None:
            backend.close(failed)
    return results
