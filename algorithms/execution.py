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
Threads, local processes and a local cluster use at most WORKERS_PER_CORE workers per core of this machine:
more only share the cores and multiply the memory (each holds a tile); run_tasks warns when it uses fewer
than asked.

Inside QGIS `sys.executable` is the QGIS binary, not Python: worker processes are started with the
interpreter of this Python (`python_executable`, set through multiprocessing.set_executable), which
both the local processes and Dask's nannies use. In worker processes each task runs with GDAL's block cache
held to raster_cache.STEP_CACHE. Local worker processes start with glibc's malloc returning freed memory above
64 KB to the system (WORKER_ENVIRONMENT, what Dask's nannies set for theirs): otherwise glibc raises its mmap
threshold as large arrays are freed, serves the next ones from its heap, and a long-lived worker's resident
memory creeps up with the number of tiles it has run, i.e. with the scene. A step that runs several rounds of
tasks keeps its workers across them (`session`). Worker processes ignore Ctrl+C (a terminal sends SIGINT to the
whole process group): they start with SIGINT blocked, and the step's process cancels them (below).

A dead worker. Dask reruns the task of a worker that dies on another worker (distributed's allowed-failures).
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
threading.Event for threads, one byte of shared memory for local processes, and a Dask Event for dask (a task
asks the scheduler at most every DASK_CHECK s). Pending tasks are cancelled; running ones are given GRACE s to
stop, after which local worker processes are killed (their temporary files go with the step's work folder, or
with the next write into their folder: atomic's leftovers); threads cannot be killed and are waited for.
qgis_process cancels the feedback on Ctrl+C only when its Qt event loop runs, which it does not while an
algorithm runs: `Execution.host_events` (the plugin's execution_choice sets it) is called while run_tasks waits.

Failure modes: InputError for unusable settings (an unknown backend, no worker, a malformed scheduler
address); ExecutionError when no Dask scheduler answers at `address` within `connect_timeout` s, when a local
worker process dies, or when no Python interpreter can be found; a task's own exception is raised as it is
(other than the engine's own errors, with the worker's traceback as a note); CancelledError when cancelled.
The design follows the cluster abstraction of CNES CARS (create tasks, start them, iterate over the futures as
they complete).

Memory on Dask: what all of a round's tasks share (a step's job: models, images, parameters) is sent to
the workers once and passed as a future, and each task is let go as soon as its result is in, so that the
scheduler does not hold a copy of the job per task, nor the results of the finished ones.

Quiet Dask: a local cluster's start prints warnings that say nothing about the run (DASK_NOISE: tornado's
deprecation of make_current, the workers' "scratch directories" on a loaded machine); they are filtered, by
message and category, in this process while the cluster starts and in its worker processes. qgis_process ends
without running Python's exit handlers, so the multiprocessing objects still alive then leave their semaphores
to the resource tracker, which reports them as leaked: the cluster is closed and collected at the end of its
step, releasing its nannies' queues. The local pool has no semaphore (pipes and one byte of shared memory)."""
import collections
import concurrent.futures as cf
import contextlib
import gc
import multiprocessing
import multiprocessing.connection
import os
import pickle
import re
import signal
import sys
import threading
import time
import traceback
import uuid
import warnings
from dataclasses import dataclass, field
from multiprocessing import resource_tracker
from multiprocessing.reduction import ForkingPickler
from typing import Callable, Optional

from . import progress, raster_cache
from .errors import CancelledError, ExecutionError, InputError, PushbroomError

BACKENDS = ("threads", "processes", "dask")
#: the environment a process pool's workers start with (module docstring; distributed's
#: nanny.pre-spawn-environ sets the same for Dask's workers)
WORKER_ENVIRONMENT = {"MALLOC_TRIM_THRESHOLD_": "65536"}
#: the most workers per core of this machine (threads, local processes, a local cluster's processes)
WORKERS_PER_CORE = 4
#: s between two looks at the pending tasks and the cancel button
POLL = 0.1
#: s the running tasks of a failed or cancelled round are given to stop before their worker processes are killed
GRACE = 10.0
#: s a task on Dask waits between two looks at the cancel token (each asks the scheduler)
DASK_CHECK = 1.0
#: warnings a Dask local cluster gives on every start (the start of the message, the category)
DASK_NOISE = (("make_current is deprecated", DeprecationWarning),
              ("Creating scratch directories is taking a surprisingly long time", UserWarning))
#: the scheduler addresses Pushbroom connects to: [tcp:// or tls://]host:port (host a name, IPv4 or [IPv6])
_ADDRESS = re.compile(r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
                      r":(?P<port>[0-9]{1,5})")


def worker_limit() -> int:
    """The most workers this machine's cores take (WORKERS_PER_CORE per core)."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_address(address: str) -> str:
    """`address` if it is a Dask scheduler address Pushbroom can connect to ([tcp:// or tls://]host:port; empty:
    a local cluster); InputError saying the expected form otherwise."""
    if not address:
        return address
    form = ("give the scheduler's address as tcp://host:port (e.g. tcp://10.0.0.5:8786, what `dask scheduler` "
            "prints) or tls://host:port, or leave it empty for a local cluster")
    found = _ADDRESS.fullmatch(address)
    if found is None:
        raise InputError(f"the Dask scheduler address {address!r} is not of the form protocol://host:port: {form}")
    if found["scheme"] and found["scheme"].lower() not in ("tcp", "tls"):
        raise InputError(f"the Dask scheduler address {address!r} uses the protocol {found['scheme']}://, which "
                         f"Pushbroom does not connect with: {form}")
    if not 0 < int(found["port"]) < 65536:
        raise InputError(f"the Dask scheduler address {address!r} has no valid port (1 to 65535): {form}")
    return address


@dataclass(frozen=True)
class Execution:
    """Where tile tasks run (module docstring); each is an advanced Processing parameter, but host_events."""

    backend: str = "threads"
    workers: int = 2                    # threads, processes, or the LocalCluster's worker processes
    address: str = ""                   # Dask scheduler address; empty: a LocalCluster of `workers`
    connect_timeout: float = 30.0       # s to wait for the scheduler at `address`
    # called while run_tasks waits for tasks: the host program's event loop (module docstring)
    host_events: Optional[Callable[[], None]] = field(default=None, compare=False, repr=False)

    def used_workers(self) -> int:
        """The workers started: `workers`, at most worker_limit() (a remote cluster has its own)."""
        return min(int(self.workers), worker_limit())

    def capped(self) -> Optional[str]:
        """The warning that fewer workers are used than asked for, or None."""
        if self.address or self.used_workers() == int(self.workers):
            return None
        return (f"{int(self.workers)} workers asked for, {self.used_workers()} used: at most {WORKERS_PER_CORE} per "
                f"core of this machine ({os.cpu_count() or 1} cores); more would only share the cores and multiply "
                "the memory")

    def describe(self) -> str:
        """Where the tasks run, in words ("2 threads", "a Dask local cluster of 2 worker processes")."""
        n = self.used_workers()
        if self.backend == "threads":
            return f"{n} thread{'s' * (n != 1)}"
        if self.backend == "processes":
            return f"{n} local worker process{'es' * (n != 1)}"
        if self.address:
            return f"the Dask cluster at {self.address}"
        return f"a Dask local cluster of {n} worker process{'es' * (n != 1)}"

    def check(self) -> "Execution":
        """Raise InputError for settings no backend can use."""
        if self.backend not in BACKENDS:
            raise InputError(f"the execution must be one of {', '.join(BACKENDS)}, not {self.backend!r}")
        if int(self.workers) < 1:
            raise InputError(f"at least one worker is needed, not {self.workers}")
        if self.address and self.backend != "dask":
            raise InputError(f"a scheduler address is for the dask execution, not {self.backend}: choose dask "
                             "or leave the address empty")
        check_address(self.address)
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
def _starting_workers(environment):
    """Inside: os.environ with `environment` added (where not set already; PYTHONWARNINGS extended) and SIGINT
    blocked in this thread, for the worker processes (and threads) started inside, which inherit both; afterwards
    os.environ as it was (distributed's nannies add their pre-spawn environment to it for good). multiprocessing's
    resource tracker is started first: starting it unblocks SIGINT in the thread that does."""
    resource_tracker.ensure_running()
    with _environ_lock:
        before = dict(os.environ)
        added = {k: v for k, v in environment.items() if k not in before}
        if "PYTHONWARNINGS" in environment and before.get("PYTHONWARNINGS"):
            added["PYTHONWARNINGS"] = before["PYTHONWARNINGS"] + "," + environment["PYTHONWARNINGS"]
        os.environ.update(added)
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            for k in set(os.environ) - set(before):
                del os.environ[k]
            os.environ.update({k: v for k, v in before.items() if os.environ.get(k) != v})


# ---- the cancel token, as a task sees it

_task = threading.local()           # .token: the cancel token of the task this thread runs (is_set())


def cancelled() -> bool:
    """True once the round of tasks that the task running on this thread belongs to is cancelled (the user
    cancelled, or another task failed); False outside a task."""
    token = getattr(_task, "token", None)
    return token is not None and token.is_set()


def check_cancel():
    """Raise CancelledError where `cancelled()`: a task calls it between its stages (module docstring)."""
    if cancelled():
        raise CancelledError("cancelled by the user")


def _run(function, args, token):
    """`function(*args)` with `token` as this thread's cancel token (not started where it is set already)."""
    outer, _task.token = getattr(_task, "token", None), token
    try:
        check_cancel()
        return function(*args)
    finally:
        _task.token = outer


def in_worker(function, args, token=None):
    """Task wrapper of a worker process (local processes and Dask): `function(*args)` with the worker's GDAL cache
    held to the steps' bound (raster_cache.hold_in_worker) and `token` as its cancel token."""
    raster_cache.hold_in_worker()
    return _run(function, args, token)


class _SharedFlag:
    """The cancel token of local worker processes: one byte of shared memory (set: 1)."""

    def __init__(self, value):
        self.value = value          # multiprocessing RawValue("b")

    def is_set(self):
        return self.value.value != 0


class _DaskFlag:
    """The cancel token of a Dask round: the distributed Event named `name`, asked at most every DASK_CHECK s
    (each look is a message to the scheduler); the name alone travels with the tasks."""

    def __init__(self, name):
        self.name, self.seen, self.at = name, False, -float("inf")

    def __reduce__(self):
        return _DaskFlag, (self.name,)

    def is_set(self):
        if not self.seen and time.monotonic() - self.at >= DASK_CHECK:
            import distributed
            with contextlib.suppress(Exception):        # no answer: not cancelled (the task runs to its end)
                self.seen = bool(distributed.Event(self.name).is_set())
            self.at = time.monotonic()
        return self.seen


# ---- the backends: begin(what), prepare(tasks), submit(function, args) -> future, done(futures) -> the finished,
# cancel(futures): set the token and give the running tasks GRACE s to stop, close(cancel);
# `note`: the warning run_tasks gives once (Execution.capped)

class _Threads:
    """threads: concurrent.futures' thread pool; a threading.Event per round as the cancel token."""

    def __init__(self, execution):
        self.note = execution.capped()
        self.pool = cf.ThreadPoolExecutor(execution.used_workers())
        self.token = threading.Event()

    def begin(self, what):
        self.token = threading.Event()

    def prepare(self, tasks):
        return tasks, []

    def submit(self, function, args):
        return self.pool.submit(_run, function, args, self.token)

    def done(self, futures):
        return cf.wait(futures, timeout=POLL, return_when=cf.FIRST_COMPLETED)[0]

    def cancel(self, futures):
        self.token.set()                # close waits for the running ones (a thread cannot be stopped)

    def close(self, cancel):
        self.pool.shutdown(wait=True, cancel_futures=cancel)


def _serve(conn, flag):
    """A local worker process (_Processes): say it waits (None), run each task it is sent and send back
    (True, result) or (False, exception); end at None, or when the step's process has gone (EOF)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    token, reply = _SharedFlag(flag), None
    while True:
        try:
            try:
                data = ForkingPickler.dumps(reply)
            except Exception as exc:            # a result that cannot be pickled
                data = ForkingPickler.dumps((False, ExecutionError(
                    f"the result of a task could not be sent back from worker process {os.getpid()}: {exc}")))
            conn.send_bytes(data)
            message = conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            task = pickle.loads(message)
            if task is None:
                return
            reply = (True, in_worker(*task, token))
        except BaseException as exc:            # SIGINT is ignored: a task's exception, or SystemExit
            reply = (False, _portable(exc))


def _portable(exc):
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

    def __init__(self, context, flag):
        conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, flag), name="pushbroom worker", daemon=True)
        with _starting_workers(WORKER_ENVIRONMENT):
            self.process.start()
        child.close()               # its end is the worker's alone: its death closes the pipe
        self.conn, self.task, self.waits = conn, None, False


class _Processes:
    """processes: local worker processes over pipes (module docstring); started as the tasks need them."""

    def __init__(self, execution):
        _use_python_for_workers()
        self.note = execution.capped()
        self.size = execution.used_workers()
        self.context = multiprocessing.get_context("spawn")
        self.flag = self.context.RawValue("b", 0)
        self.workers, self.queue, self.what = [], collections.deque(), "the tiles"

    def begin(self, what):
        self.what = what
        self.flag.value = 0

    def prepare(self, tasks):
        """The tasks as they are submitted (pickled per task)."""
        return tasks, []

    def submit(self, function, args):
        future = cf.Future()
        self.queue.append((future, (function, args)))
        return future

    def done(self, futures):
        self._dispatch()
        self._receive(POLL)
        self._dispatch()
        return {f for f in futures if f.done()}

    def cancel(self, futures):
        """Set the token; wait until the busy workers have stopped (or died), GRACE s at most."""
        self.flag.value = 1
        for future, _ in self.queue:
            future.cancel()
        self.queue.clear()
        deadline = time.monotonic() + GRACE
        while any(w.task is not None for w in self.workers) and time.monotonic() < deadline:
            with contextlib.suppress(ExecutionError):           # a worker that dies meanwhile has stopped
                self._receive(min(POLL, max(deadline - time.monotonic(), 0.0)))

    def _dispatch(self):
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
                worker.conn.send(task)          # it reads as it waits: returns once the worker has it all
            except (EOFError, OSError):
                raise self._lost(worker) from None
            except Exception as exc:            # the task's arguments cannot be pickled (before a byte is sent)
                future.set_exception(exc)
                worker.task, worker.waits = None, True
                waiting.append(worker)

    def _receive(self, timeout):
        """Wait up to `timeout` s for a worker's message or death, and take what came (ExecutionError for a death)."""
        if not self.workers:
            time.sleep(timeout)
            return
        ready = multiprocessing.connection.wait([w.conn for w in self.workers] +
                                                [w.process.sentinel for w in self.workers], timeout)
        for worker in [w for w in self.workers if w.conn in ready or w.process.sentinel in ready]:
            try:
                while worker.conn.poll():
                    message = worker.conn.recv()
                    future, worker.task, worker.waits = worker.task, None, True
                    if future is None:
                        continue                # the worker's first message: it waits
                    ok, value = message
                    if ok:
                        future.set_result(value)
                    else:
                        future.set_exception(value)
            except (EOFError, OSError):
                raise self._lost(worker) from None
            if worker.process.sentinel in ready:
                raise self._lost(worker)

    def _lost(self, worker):
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
        return ExecutionError(f"{self.what}: worker process {worker.process.pid} died ({cause}) "
                              f"{'with a task' if worker.task else 'between tasks'}: "
                              "run again with fewer workers or smaller tiles, or choose the threads execution")

    def close(self, cancel):
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


@contextlib.contextmanager
def _quiet_dask():
    """DASK_NOISE filtered in this process inside the block (module docstring)."""
    with warnings.catch_warnings():
        for message, category in DASK_NOISE:
            warnings.filterwarnings("ignore", message=re.escape(message), category=category)
        yield


class _Dask:
    """Dask distributed: a LocalCluster of single-threaded worker processes, or the scheduler at an address."""

    def __init__(self, execution):
        try:
            import distributed
        except ImportError as exc:
            raise ExecutionError("the dask execution needs Dask distributed (python3-distributed), which is not "
                                 "installed: run `make setup`, or choose threads or processes") from exc
        self.note, self.cluster, self.token = execution.capped(), None, _DaskFlag("")
        if execution.address:
            try:
                self.client = distributed.Client(execution.address, timeout=f"{execution.connect_timeout}s",
                                                 set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise ExecutionError(f"no Dask scheduler answers at {execution.address} within "
                                     f"{execution.connect_timeout:g} s ({exc}): start one (`dask scheduler`) and "
                                     "its workers (`dask worker <address>`), or leave the address empty for a "
                                     "local cluster") from None
            except Exception as exc:        # e.g. tls:// without Dask's TLS configuration
                raise ExecutionError(f"cannot connect to the Dask scheduler at {execution.address} ({exc}): check "
                                     "the address, and for tls:// Dask's TLS configuration (distributed.comm.tls)"
                                     ) from None
            return
        _use_python_for_workers()
        quiet = ",".join(f"ignore:{message}:{category.__name__}" for message, category in DASK_NOISE)
        with _quiet_dask(), _starting_workers({"PYTHONWARNINGS": quiet}):
            # no dashboard; the scheduler's HTTP server (health, metrics) on a free local port, not on 8787, which
            # another cluster may hold ("Port 8787 is already in use")
            self.cluster = distributed.LocalCluster(n_workers=execution.used_workers(), threads_per_worker=1,
                                                    processes=True, dashboard_address=None,
                                                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                                    silence_logs=40)        # logging.ERROR
            try:
                self.client = distributed.Client(self.cluster, set_as_default=False)
            except BaseException:
                self.close(True)
                raise

    def begin(self, what):
        self.token = _DaskFlag(f"pushbroom-cancel-{uuid.uuid4().hex}")

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
        return self.client.submit(in_worker, function, args, self.token, pure=False)

    def done(self, futures):
        done = {f for f in futures if f.done()}
        if not done:
            time.sleep(POLL)
        return done

    def cancel(self, futures):
        """Set the round's Event (it stays on the scheduler, a name) and wait until the round's `futures` are
        done, GRACE s at most (closing a local cluster would kill the tasks wherever they are)."""
        if not self.token.name:         # no round began
            return
        with contextlib.suppress(Exception):
            self.client.sync(self.client.scheduler.event_set, name=self.token.name, callback_timeout=GRACE)
        deadline = time.monotonic() + GRACE
        while not all(f.done() for f in futures) and time.monotonic() < deadline:
            time.sleep(POLL)

    def close(self, cancel):
        with _quiet_dask():
            with contextlib.suppress(Exception):
                self.client.close()
            if self.cluster is not None:
                with contextlib.suppress(Exception):
                    self.cluster.close()
                self.cluster = None
                gc.collect()            # the nannies' queues, with their semaphores


def _backend(execution):
    return {"threads": _Threads, "processes": _Processes, "dask": _Dask}[execution.backend](execution)


_sessions = {}          # (thread, Execution) -> the backend a `session` keeps


@contextlib.contextmanager
def session(execution=None):
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
        backend.close(cancel=failed)        # run_tasks has cancelled a failed round's tasks


def run_tasks(function, tasks, execution=None, feedback=None, what="the tiles"):
    """Run `function(*args)` for each `args` of the list `tasks` on `execution` (Execution; default
    threads) and return the results in the order of `tasks`. Progress runs 0-100 % over the tasks;
    a cancel stops the pending tasks, asks the running ones to stop (`check_cancel`) and raises CancelledError;
    the first task to fail does the same to the others and its exception is raised (module docstring)."""
    execution = (execution or Execution()).check()
    tasks = list(tasks)
    results = [None] * len(tasks)
    if not tasks:
        return results
    kept = _sessions.get((threading.get_ident(), execution))
    backend = kept or _backend(execution)
    progress.warn(feedback, backend.note)           # once per backend
    backend.note = None
    progress.ensure(feedback).pushInfo(f"{what}: {len(tasks)} task{'s' * (len(tasks) != 1)} on {execution.describe()}")
    futures, failed = {}, True
    try:
        backend.begin(what)
        submitted, shared = backend.prepare(tasks)
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
                results[futures.pop(future)] = future.result()
                progress.step(feedback, 100.0 * (len(tasks) - len(pending)) / len(tasks))
        failed = False
        del shared
    finally:
        if failed:
            backend.cancel(futures)         # the running tasks stop at their next look at the token
            for future in futures:
                future.cancel()
        if kept is None:
            backend.close(failed)
    return results
