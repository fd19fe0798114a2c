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
- "processes": a pool of local worker processes started by `spawn`;
- "dask": Dask distributed, on a LocalCluster of `workers` single-threaded worker processes, or on the
  cluster whose scheduler listens at `address` (e.g. tcp://host:8786; every worker must see the
  same files under the same paths and import pushbroom).

Inside QGIS `sys.executable` is the QGIS binary, not Python: worker processes are started with the
interpreter of this Python (`python_executable`, set through multiprocessing.set_executable), which
both the process pool and Dask's nannies use. Dask reruns the task of a worker that dies on another
worker (distributed's allowed-failures); the process pool cannot, and reports which step failed.
In worker processes each task runs with GDAL's block cache held to raster_cache.STEP_CACHE. The process
pool's workers start with glibc's malloc returning freed memory above 64 KB to the system
(WORKER_ENVIRONMENT, what Dask's nannies set for theirs): otherwise glibc raises its mmap threshold as large
arrays are freed, serves the next ones from its heap, and a long-lived worker's resident memory creeps up
with the number of tiles it has run, i.e. with the scene. A step that runs several rounds of tasks keeps its
workers across them (`session`).

Failure modes: InputError for unknown settings; ExecutionError when no Dask scheduler answers at
`address` within `connect_timeout` s, when a worker process dies, or when no Python interpreter can
be found; a task's own exception is raised as it is; CancelledError when cancelled (pending tasks
are cancelled, running ones finish and are discarded). The design follows the cluster abstraction of
CNES CARS (create tasks, start them, iterate over the futures as they complete).

Memory on Dask: what all of a round's tasks share (a step's job: models, images, parameters) is sent to
the workers once and passed as a future, and each task is let go as soon as its result is in, so that the
scheduler does not hold a copy of the job per task, nor the results of the finished ones."""
import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import sys
import threading
import time
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

from . import progress
from .errors import CancelledError, ExecutionError, InputError
from .raster_cache import in_worker

BACKENDS = ("threads", "processes", "dask")
#: the environment a process pool's workers start with (module docstring; distributed's
#: nanny.pre-spawn-environ sets the same for Dask's workers)
WORKER_ENVIRONMENT = {"MALLOC_TRIM_THRESHOLD_": "65536"}
#: s between two looks at the pending tasks and the cancel button
POLL = 0.1


@dataclass(frozen=True)
class Execution:
    """Where tile tasks run (module docstring); each is an advanced Processing parameter."""

    backend: str = "threads"
    workers: int = 2                    # threads, processes, or the LocalCluster's worker processes
    address: str = ""                   # Dask scheduler address; empty: a LocalCluster of `workers`
    connect_timeout: float = 30.0       # s to wait for the scheduler at `address`

    def describe(self):
        """Where the tasks run, in words ("2 threads", "a Dask local cluster of 2 worker processes")."""
        n = int(self.workers)
        if self.backend == "threads":
            return f"{n} thread{'s' * (n != 1)}"
        if self.backend == "processes":
            return f"{n} local worker process{'es' * (n != 1)}"
        if self.address:
            return f"the Dask cluster at {self.address}"
        return f"a Dask local cluster of {n} worker process{'es' * (n != 1)}"

    def check(self):
        """Raise InputError for settings no backend can use."""
        if self.backend not in BACKENDS:
            raise InputError(f"the execution must be one of {', '.join(BACKENDS)}, not {self.backend!r}")
        if int(self.workers) < 1:
            raise InputError(f"at least one worker is needed, not {self.workers}")
        if self.address and self.backend != "dask":
            raise InputError(f"a scheduler address is for the dask execution, not {self.backend}: choose dask "
                             "or leave the address empty")
        return self


def python_executable():
    """The Python interpreter worker processes start: sys.executable where it is this Python's (inside
    sys.prefix: the system's or the venv's), else the interpreter of this Python's installation. Inside
    QGIS sys.executable is the QGIS binary, or whatever `python3` comes first on PATH (embedded Python
    guesses it), possibly another installation whose standard library does not fit this one."""
    exe = os.path.abspath(sys.executable or "")
    if os.path.basename(exe).lower().startswith("python") and exe.startswith(os.path.abspath(sys.prefix) + os.sep):
        return exe
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    candidates = [os.path.join(prefix, "bin", name) for prefix in (sys.exec_prefix, sys.base_exec_prefix)
                  for name in (f"python{version}", "python3")]          # a venv's first: it has the packages
    candidates += [os.path.join(sys.base_exec_prefix, "python.exe")]
    for candidate in candidates:
        if os.path.isfile(candidate) and os.access(candidate, os.X_OK):
            return candidate
    raise ExecutionError(f"no Python {version} interpreter found under {sys.base_exec_prefix} to start worker "
                         f"processes (this program runs as {sys.executable}): choose the threads execution")


def _use_python_for_workers():
    exe = python_executable()
    if exe != sys.executable:
        multiprocessing.set_executable(exe)


_environ_lock = threading.Lock()


@contextlib.contextmanager
def _worker_environment():
    """os.environ with WORKER_ENVIRONMENT (where not set already) for the worker processes started inside,
    as it was afterwards."""
    with _environ_lock:
        added = {k: v for k, v in WORKER_ENVIRONMENT.items() if k not in os.environ}
        os.environ.update(added)
        try:
            yield
        finally:
            for k in added:
                os.environ.pop(k, None)


class _Pool:
    """threads / processes: concurrent.futures."""

    def __init__(self, execution):
        self.threads = execution.backend == "threads"
        if self.threads:
            self.pool = cf.ThreadPoolExecutor(int(execution.workers))
        else:
            _use_python_for_workers()
            self.pool = cf.ProcessPoolExecutor(int(execution.workers), mp_context=multiprocessing.get_context("spawn"))

    def prepare(self, tasks):
        """The tasks as they are submitted (a pool passes every argument by reference or pickles it per task)."""
        return tasks, []

    def submit(self, function, args):
        if self.threads:
            return self.pool.submit(function, *args)
        with _worker_environment():         # the pool starts its workers as the first tasks arrive
            return self.pool.submit(in_worker, function, args)

    def done(self, futures):
        return cf.wait(futures, timeout=POLL, return_when=cf.FIRST_COMPLETED)[0]

    def result(self, future, what):
        try:
            return future.result()
        except BrokenProcessPool as exc:
            raise ExecutionError(f"a worker process of {what} died (out of memory, or killed): run again with "
                                 "fewer workers or smaller tiles") from exc

    def close(self, cancel):
        self.pool.shutdown(wait=True, cancel_futures=cancel)


class _Dask:
    """Dask distributed: a LocalCluster of single-threaded worker processes, or the scheduler at an address."""

    def __init__(self, execution):
        try:
            import distributed
        except ImportError as exc:
            raise ExecutionError("the dask execution needs Dask distributed (python3-distributed), which is not "
                                 "installed: run `make setup`, or choose threads or processes") from exc
        self.cluster = None
        if execution.address:
            try:
                self.client = distributed.Client(execution.address, timeout=f"{execution.connect_timeout}s",
                                                 set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise ExecutionError(f"no Dask scheduler answers at {execution.address} within "
                                     f"{execution.connect_timeout:g} s ({exc}): start one (`dask scheduler`) and "
                                     "its workers (`dask worker <address>`), or leave the address empty for a "
                                     "local cluster") from None
        else:
            _use_python_for_workers()
            self.cluster = distributed.LocalCluster(n_workers=int(execution.workers), threads_per_worker=1,
                                                    processes=True, dashboard_address=None,
                                                    silence_logs=40)        # logging.ERROR
            try:
                self.client = distributed.Client(self.cluster, set_as_default=False)
            except BaseException:
                self.cluster.close()
                raise

    def prepare(self, tasks):
        """(tasks, futures to keep): each object that every task passes at the same place (a step's job: its
        models, images and parameters) sent to the workers once (scatter, to every worker) and passed as its
        future, which the workers resolve: the scheduler holds it once, not once per task."""
        shared = {}
        if len(tasks) > 1:
            for i, value in enumerate(tasks[0]):
                if isinstance(value, (str, bytes, int, float, bool, type(None))):
                    continue
                if all(len(t) > i and t[i] is value for t in tasks):
                    # in a list: scatter sends a tuple's items one by one, a list's items as they are
                    shared[i] = self.client.scatter([value], broadcast=True, hash=False)[0]
        if not shared:
            return tasks, []
        return [tuple(shared.get(i, a) for i, a in enumerate(t)) for t in tasks], list(shared.values())

    def submit(self, function, args):
        # pure=False: a task is run, not looked up (two runs of the same tile may write different files)
        return self.client.submit(in_worker, function, args, pure=False)

    def done(self, futures):
        done = {f for f in futures if f.done()}
        if not done:
            time.sleep(POLL)
        return done

    def result(self, future, what):
        return future.result()

    def close(self, cancel):
        with contextlib.suppress(Exception):
            self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()


_sessions = {}          # (thread, Execution) -> the backend a `session` keeps


@contextlib.contextmanager
def session(execution=None):
    """Keep the worker processes (the pool, or the Dask LocalCluster or client) of `execution` for every
    run_tasks of it on this thread inside the block, so that a step that runs several rounds of tasks starts
    its workers once; they are closed when the block ends. Threads need no session."""
    execution = (execution or Execution()).check()
    key = (threading.get_ident(), execution)
    if execution.backend == "threads" or key in _sessions:
        yield
        return
    _sessions[key] = backend = _Dask(execution) if execution.backend == "dask" else _Pool(execution)
    try:
        yield
    finally:
        del _sessions[key]
        backend.close(cancel=True)


def run_tasks(function, tasks, execution=None, feedback=None, what="the tiles"):
    """Run `function(*args)` for each `args` of the list `tasks` on `execution` (Execution; default
    threads) and return the results in the order of `tasks`. Progress runs 0-100 % over the tasks;
    a cancel stops the pending ones and raises CancelledError; the first task to fail cancels the
    others and its exception is raised (module docstring)."""
    execution = (execution or Execution()).check()
    tasks = list(tasks)
    results = [None] * len(tasks)
    if not tasks:
        return results
    progress.ensure(feedback).pushInfo(f"{what}: {len(tasks)} task{'s' * (len(tasks) != 1)} on {execution.describe()}")
    kept = _sessions.get((threading.get_ident(), execution))
    backend = kept or (_Dask(execution) if execution.backend == "dask" else _Pool(execution))
    futures, cancel = {}, True
    try:
        submitted, shared = backend.prepare(tasks)
        for k, args in enumerate(submitted):
            futures[backend.submit(function, args)] = k
        pending = set(futures)
        while pending:
            if feedback is not None and feedback.isCanceled():
                raise CancelledError("cancelled by the user")
            for future in backend.done(pending):
                pending.discard(future)
                # a finished task is let go at once: Dask then forgets its result and its arguments
                results[futures.pop(future)] = backend.result(future, what)
                progress.step(feedback, 100.0 * (len(tasks) - len(pending)) / len(tasks))
        cancel = False
        del shared
    finally:
        if cancel:
            for future in futures:
                future.cancel()
        if kept is None:
            backend.close(cancel)
    return results
