"""The command that checks every worker of a Dask cluster (README, "Scaling out"):

    python3 -m pushbroom.algorithms.worker_check tcp://node1:8786

prints a line per worker (its address, host, Python, and Pushbroom's version or what it misses: worker_report.py)
and a count; exits with 1 where a worker cannot run Pushbroom's tasks, 2 where no scheduler answers or it has no
worker."""

import platform
import sys
from typing import Optional

from ..version import VERSION
from .dask_backend import worker_reports
from .errors import PushbroomError
from .worker_report import dense_missing, describe, problems


def main(argv: Optional[list] = None) -> int:
    """The command line (module docstring)."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python3 -m pushbroom.algorithms.worker_check",
        description="Check that every worker of a Dask cluster can run Pushbroom's tasks.",
    )
    parser.add_argument("address", help="the scheduler's address, tcp://host:port")
    parser.add_argument("--timeout", type=float, default=30.0, help="s to wait for the scheduler (30)")
    args = parser.parse_args(argv)
    try:
        reports = worker_reports(args.address, args.timeout)
    except PushbroomError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not reports:
        print(f"error: the Dask scheduler at {args.address} has no worker", file=sys.stderr)
        return 2
    failing = 0
    for address, seen in sorted(reports.items()):
        said = problems(seen, VERSION, platform.python_version())
        failing += bool(said)
        dense = dense_missing(seen)
        status = (
            "FAILS: " + "; ".join(said)
            if said
            else "ok" + (f" (not for dense matching: {'; '.join(dense)})" if dense else "")
        )
        print(f"{describe(address, seen)}: {status}")
    print(f"{len(reports) - failing} of {len(reports)} workers run Pushbroom {VERSION}")
    return 1 if failing else 0


if __name__ == "__main__":
    sys.exit(main())
