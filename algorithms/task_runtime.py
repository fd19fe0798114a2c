"""Where tile tasks run and what a task sees there: the execution's settings (`Execution`), the Python, environment
and signals worker processes start with, and the cancel token of the task running on a thread. execution.py runs
the tasks (threads, local processes) and dask_backend.py on Dask; both build on this module.

Inside QGIS `sys.executable` is the QGIS binary, not Python: worker processes are started with the
interpreter of this Python (`python_executable`, set through multiprocessing.set_executable), which
both the local processes and Dask's nannies use. In worker processes each task runs with GDAL's block cache
held to raster_cache.STEP_CACHE. Local worker processes start with glibc's malloc returning freed memory above
64 KB to the system (WORKER_ENVIRONMENT, what Dask's nannies set for theirs): otherwise glibc raises its mmap
threshold as large arrays are freed, serves the next ones from its heap, and a long-lived worker's resident
memory creeps up with the number of tiles it has run, i.e. with the scene. Worker processes ignore Ctrl+C (a
terminal sends SIGINT to the whole process group): they start with SIGINT blocked (`starting_workers`), and the
step's process cancels them (execution.py).

A task asks its round's cancel token between its stages (`cancelled`, `check_cancel`): a threading.Event for
threads, one byte of shared memory for local processes, a Dask Event on Dask (execution.py, dask_backend.py)."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import re
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from multiprocessing import resource_tracker
from typing import Any, Protocol, TypeVar

from . import raster_cache
from .errors import CancelledError, ExecutionError, InputError

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
#: the scheduler addresses Pushbroom connects to: [tcp:// or tls://]host:port (host a name, IPv4 or [IPv6])
_ADDRESS = re.compile(
    r"(?:(?P<scheme>[A-Za-z][A-Za-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
    r":(?P<port>[0-9]{1,5})"
)


def worker_limit() -> int:
    """The most workers this machine's cores take (WORKERS_PER_CORE per core)."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_address(address: str) -> str:
    """`address` if it is a Dask scheduler address Pushbroom can connect to ([tcp:// or tls://]host:port; empty:
    a local cluster); InputError saying the expected form otherwise."""
    if not address:
        return address
    form = (
        "give the scheduler's address as tcp://host:port (e.g. tcp://10.0.0.5:8786, what `dask scheduler` "
        "prints) or tls://host:port, or leave it empty for a local cluster"
    )
    found = _ADDRESS.fullmatch(address)
    if found is None:
        raise InputError(f"the Dask scheduler address {address!r} is not of the form protocol://host:port: {form}")
    if found["scheme"] and found["scheme"].lower() not in ("tcp", "tls"):
        raise InputError(
            f"the Dask scheduler address {address!r} uses the protocol {found['scheme']}://, which "
            f"Pushbroom does not connect with: {form}"
        )
    if not 0 < int(found["port"]) < 65536:
        raise InputError(f"the Dask scheduler address {address!r} has no valid port (1 to 65535): {form}")
    return address


@dataclass(frozen=True)
class Execution:
    """Where tile tasks run (module docstring); each is an advanced Processing parameter, but host_events."""

    backend: str = "threads"
    workers: int = 2  # threads, processes, or the LocalCluster's worker processes
    address: str = ""  # Dask scheduler address; empty: a LocalCluster of `workers`
    connect_timeout: float = 30.0  # s to wait for the scheduler at `address`
    worker_wait: float = 60.0  # s a round on Dask waits for a worker where the cluster has none or lost all
    # called while run_tasks waits for tasks: the host program's event loop (module docstring)
    host_events: Callable[[], None] | None = field(default=None, compare=False, repr=False)

    def used_workers(self) -> int:
        """The workers started: `workers`, at most worker_limit() (a remote cluster has its own)."""
        return min(int(self.workers), worker_limit())

    def capped(self) -> str | None:
        """The warning that fewer workers are used than asked for, or None."""
        if self.address or self.used_workers() == int(self.workers):
            return None
        return (
            f"{int(self.workers)} workers asked for, {self.used_workers()} used: at most {WORKERS_PER_CORE} per "
            f"core of this machine ({os.cpu_count() or 1} cores); more would only share the cores and multiply "
            "the memory"
        )

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

    def check(self) -> Execution:
        """Raise InputError for settings no backend can use."""
        if self.backend not in BACKENDS:
            raise InputError(f"the execution must be one of {', '.join(BACKENDS)}, not {self.backend!r}")
        if int(self.workers) < 1:
            raise InputError(f"at least one worker is needed, not {self.workers}")
        if self.address and self.backend != "dask":
            raise InputError(
                f"a scheduler address is for the dask execution, not {self.backend}: choose dask "
                "or leave the address empty"
            )
        check_address(self.address)
        return self


def python_executable() -> str:
    """The Python interpreter worker processes start: sys.executable where it is this Python's (inside
    sys.prefix: the system's or the venv's), else the interpreter of this Python's installation. Inside
    QGIS sys.executable is the QGIS binary, or whatever `python3` comes first on PATH (embedded Python
    guesses it), possibly another installation whose standard library does not fit this one."""
    exe = os.path.abspath(sys.executable or "")
    if os.path.basename(exe).lower().startswith("python") and exe.startswith(os.path.abspath(sys.prefix) + os.sep):
        return exe
    version = f"{sys.version_info.major}.{sys.version_info.minor}"
    candidates = [
        os.path.join(prefix, "bin", name)
        for prefix in (sys.exec_prefix, sys.base_exec_prefix)
        for name in (f"python{version}", "python3")
    ]  # a venv's first: it has the packages
    candidates += [os.path.join(sys.base_exec_prefix, "python.exe")]
    for candidate in candidates:
        if os.path.isfile(candidate) and os.access(candidate, os.X_OK):
            return candidate
    raise ExecutionError(
        f"no Python {version} interpreter found under {sys.base_exec_prefix} to start worker "
        f"processes (this program runs as {sys.executable}): choose the threads execution"
    )


def use_python_for_workers() -> None:
    """multiprocessing starts python_executable() (module docstring)."""
    exe = python_executable()
    if exe != sys.executable:
        multiprocessing.set_executable(exe)


_environ_lock = threading.Lock()


@contextlib.contextmanager
def starting_workers(environment: Mapping[str, str]) -> Iterator[None]:
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

T = TypeVar("T")


class CancelToken(Protocol):
    """A round's cancel token as a task asks it: threading.Event (threads), execution._SharedFlag (local
    processes), dask_backend._DaskFlag (Dask)."""

    def is_set(self) -> bool: ...


_task = threading.local()  # .token: the cancel token of the task this thread runs (is_set())


def cancelled() -> bool:
    """True once the round of tasks that the task running on this thread belongs to is cancelled (the user
    cancelled, or another task failed); False outside a task."""
    token = getattr(_task, "token", None)
    return token is not None and token.is_set()


def check_cancel() -> None:
    """Raise CancelledError where `cancelled()`: a task calls it between its stages (module docstring)."""
    if cancelled():
        raise CancelledError("cancelled by the user")


def run_with_token(function: Callable[..., T], args: Sequence[Any], token: CancelToken | None) -> T:
    """`function(*args)` with `token` as this thread's cancel token (not started where it is set already)."""
    outer, _task.token = getattr(_task, "token", None), token
    try:
        check_cancel()
        return function(*args)
    finally:
        _task.token = outer


def in_worker(function: Callable[..., T], args: Sequence[Any], token: CancelToken | None = None) -> T:
    """Task wrapper of a worker process (local processes and Dask): `function(*args)` with the worker's GDAL cache
    held to the steps' bound (raster_cache.hold_in_worker) and `token` as its cancel token."""
    raster_cache.hold_in_worker()
    return run_with_token(function, args, token)
