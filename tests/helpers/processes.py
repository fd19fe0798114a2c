"""The processes of this machine as /proc shows them (Linux): a test's worker processes, to kill one; the pid a
task leaves in a file, and a thread that acts once a condition holds."""

import os
import threading
import time


def peak_kb(pid="self"):
    """VmHWM, the peak resident memory, of process `pid` in kB (0 where it has gone)."""
    try:
        with open(f"/proc/{pid}/status", encoding="utf-8") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def _stat(pid: int) -> list[str] | None:
    """The fields of /proc/<pid>/stat after the command name, the state first (None where it has gone)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="utf-8") as f:
            return f.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _parent(pid: int) -> int | None:
    """The parent pid of `pid` (None where it has gone)."""
    fields = _stat(pid)
    return int(fields[1]) if fields else None


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process `pid` (s; 0 where it has gone)."""
    fields = _stat(pid)
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK") if fields else 0.0


def descendants(pid):
    """The pids of the processes descending from `pid`, children first."""
    children = {}
    for name in os.listdir("/proc"):
        if name.isdigit():
            children.setdefault(_parent(int(name)), []).append(int(name))
    found, todo = [], [pid]
    while todo:
        for child in sorted(children.get(todo.pop(0), [])):
            found.append(child)
            todo.append(child)
    return found


def command_line(pid):
    """The command line of `pid` as one string ('' where it has gone)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def worker_processes(pid: int) -> list[int]:
    """The pids of the worker processes descending from `pid`: those multiprocessing spawned (its spawn_main in
    their command line: the local pool's and the Dask local cluster's workers), children first."""
    return [child for child in descendants(pid) if "spawn_main" in command_line(child)]


def pid_in(path) -> int | None:
    """The pid a task left in the file `path` (None where the file is not there, or not written yet)."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError:
        return None
    return int(text) if text.strip() else None


def when(condition, then, timeout: float = 120.0) -> threading.Thread:
    """A thread that runs `then()` once `condition()` holds, looking every 0.05 s for `timeout` s at most."""

    def watch():
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if condition():
                then()
                return
            time.sleep(0.05)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread
