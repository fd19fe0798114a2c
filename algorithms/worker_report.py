"""Whether a Dask worker can run Pushbroom's tasks, as the worker itself sees it.

`report()` runs on each worker (distributed's Client.run). The Dask backend (dask_backend.py) sends this module's
functions by value (cloudpickle.register_pickle_by_value), so a worker that cannot import pushbroom still answers,
with what it misses; they therefore use the standard library only, and this module imports nothing of Pushbroom.
A worker needs the modules of NEEDED, the same Pushbroom version and the same Python minor version as the step's
process (tasks are pickled: another Python or Pushbroom may read them differently); dense matching's tiles also
need DENSE (CNES libsgm, the `dense` extra). worker_check.py is the command that checks every worker."""

import sys

#: module -> how to provide it, for the message
NEEDED = {
    "pushbroom": "install the plugin's wheel, or start the worker from the plugin's venv (README, Scaling out)",
    "numba": "install numba, a dependency of the plugin's wheel",
    "osgeo.gdal": "install Debian's python3-gdal",
}
DENSE = {"c_libsgm": "install CNES libsgm, the wheel's `dense` extra"}


def report() -> dict:
    """What this process offers: its host, Python (version, executable) and, for each module of NEEDED and DENSE,
    its version ("" where it has none) or the error importing it."""
    import importlib
    import platform
    import socket

    found, missing = {}, {}
    for name in [*NEEDED, *DENSE]:
        try:
            module = importlib.import_module(name)
            found[name] = str(getattr(module, "__version__", ""))
        except Exception as exc:  # ImportError, or a module that fails as it loads
            missing[name] = f"{type(exc).__name__}: {exc}"
    return {
        "host": socket.gethostname(),
        "python": platform.python_version(),
        "executable": sys.executable,
        "found": found,
        "missing": missing,
    }


def _missing(seen: dict, modules: dict) -> list:
    """A phrase for each module of `modules` the worker of report `seen` lacks."""
    return [
        f"no {name} ({seen['missing'][name]}: {provider})"
        for name, provider in modules.items()
        if name in seen["missing"]
    ]


def problems(seen, version: str, python: str) -> list:
    """What keeps the worker of report `seen` (report(), or the exception it answered with) from running
    Pushbroom's tasks given by a process of Pushbroom `version` and Python `python` (major.minor.micro): each a
    phrase; none where it can."""
    if isinstance(seen, BaseException):
        return [f"the check did not run ({type(seen).__name__}: {seen})"]
    said = _missing(seen, NEEDED)
    other = seen["found"].get("pushbroom")
    if other is not None and other != version:
        said.append(f"Pushbroom {other}, not {version} as the step")
    if seen["python"].split(".")[:2] != python.split(".")[:2]:
        said.append(f"Python {seen['python']} ({seen['executable']}), not {python} as the step")
    return said


def dense_missing(seen) -> list:
    """The phrases for DENSE's modules the worker of report `seen` lacks (none for a worker that did not answer)."""
    return [] if isinstance(seen, BaseException) else _missing(seen, DENSE)


def describe(address: str, seen) -> str:
    """One line for a worker: its address, host, Python and Pushbroom's version (only the address for a worker
    that did not answer)."""
    if isinstance(seen, BaseException):
        return address
    pushbroom = seen["found"].get("pushbroom")
    return f"{address} on {seen['host']}: Python {seen['python']} ({seen['executable']}), " + (
        f"Pushbroom {pushbroom}" if pushbroom is not None else "no Pushbroom"
    )
