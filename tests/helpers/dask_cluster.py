"""A Dask cluster of separate processes, as a user starts one (`dask scheduler`, `dask worker`), on this machine:
for the tests of the dask execution against a cluster that misbehaves (tests/algorithms/test_dask_cluster.py)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path
from typing import Callable

from tests.helpers.processes import descendants

REPO = Path(__file__).resolve().parents[2]


def free_port() -> int:
    """A TCP port of 127.0.0.1 nobody listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """A scheduler on 127.0.0.1 and the workers added to it, each a process group of its own (killed at the end);
    their output in `folder`. Workers run this venv's Python with the repository on PYTHONPATH (the tests' task
    functions), unless given another interpreter and environment. `scheduler(port)`, where given, is the command
    that starts the scheduler (and `env` its environment)."""

    def __init__(self, folder: Path, scheduler: Callable[[int], list] | None = None, env: dict | None = None):
        self.folder, self.port = Path(folder), free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.processes: list[subprocess.Popen] = []
        command = (
            scheduler(self.port)
            if scheduler
            else [
                sys.executable,
                "-m",
                "distributed.cli.dask_scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(self.port),
                "--no-dashboard",
            ]
        )
        self.scheduler = self.start("scheduler", command, env)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return
            time.sleep(0.1)
        raise RuntimeError(f"the test's Dask scheduler did not listen within 60 s: {self.folder}")

    def start(self, name: str, command: list, env: dict | None = None) -> subprocess.Popen:
        """Start `command` (its output in <folder>/<name>-<k>.log) in a process group of its own."""
        log = open(self.folder / f"{name}-{len(self.processes)}.log", "wb")
        environment = {**os.environ, "PYTHONPATH": str(REPO)} if env is None else env
        process = subprocess.Popen(
            command, stdout=log, stderr=subprocess.STDOUT, env=environment, start_new_session=True, cwd=self.folder
        )
        log.close()
        self.processes.append(process)
        return process

    def add_worker(
        self, python: str = sys.executable, env: dict | None = None, nanny: bool = False
    ) -> subprocess.Popen:
        """A single-threaded worker (`dask worker <address> --nworkers 1 --nthreads 1`; without a nanny, a killed
        worker stays dead)."""
        return self.start(
            "worker",
            [
                python,
                "-m",
                "distributed.cli.dask_worker",
                self.address,
                "--nworkers",
                "1",
                "--nthreads",
                "1",
                "--nanny" if nanny else "--no-nanny",
                "--no-dashboard",
                "--local-directory",
                str(self.folder),
            ],
            env,
        )

    def wait_for_workers(self, n: int, timeout: float = 60.0):
        """Return once the scheduler has `n` workers."""
        import distributed

        with warnings.catch_warnings():  # tornado's deprecation of make_current, on every client's start
            warnings.simplefilter("ignore", DeprecationWarning)
            with distributed.Client(self.address, set_as_default=False) as client:
                client.wait_for_workers(n, timeout=timeout)

    @staticmethod
    def kill(*processes: subprocess.Popen):
        """SIGKILL to the workers' whole process groups (their nannies and workers), as the OOM killer or a lost
        host: all of them before waiting for any (while the test waited for one to die, the scheduler had given its
        task to the next, which finished it before its own kill)."""
        for process in processes:
            for pid in [process.pid, *descendants(process.pid)]:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for process in processes:
            process.wait(30)

    def close(self):
        for process in reversed(self.processes):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in self.processes:
            try:
                process.wait(15)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(15)

    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc):
        self.close()


def readme_commands(readme: Path) -> dict:
    """The README's two-host example ("Two hosts, worked through"): {"settings": {name: value} of its NAME=value
    lines, "scheduler", "worker", "check": its commands}, each as written."""
    text = readme.read_text(encoding="utf-8")
    block = text[text.index("**Two hosts, worked through.**") :]
    block = block[block.index("```bash") + len("```bash") :]
    lines = [line.split("  #")[0].strip() for line in block[: block.index("```")].splitlines()]
    lines = [line for line in lines if line and not line.startswith("#")]
    found: dict = {"settings": dict(line.split("=", 1) for line in lines if "=" in line.split()[0])}
    for key, mark in (("scheduler", "dask_scheduler"), ("worker", "dask_worker"), ("check", "worker_check")):
        found[key] = next(line for line in lines if mark in line)
    return found


def readme_shell(readme: dict, command: str, settings: dict) -> list:
    """bash running the README's `command` (a key of readme_commands) as written, after its settings with those of
    `settings` in place of the README's values."""
    assignments = [f"{name}={settings.get(name, value)}" for name, value in readme["settings"].items()]
    return ["bash", "-c", "; ".join([*assignments, "exec " + readme[command]])]
