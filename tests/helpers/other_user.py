"""A process run as another user: where the tests run as root (who may write anywhere), the process that must
meet a permission refusal runs as the unprivileged user `nobody`, on files in a folder every user may read."""

import contextlib
import os
import pathlib
import shutil
import sys
import tempfile
from collections.abc import Iterator

USER = "nobody"


@contextlib.contextmanager
def public_folder(prefix: str) -> Iterator[pathlib.Path]:
    """A new folder in /tmp that every user may enter and read (pytest's temporary folders are root's alone);
    removed afterwards with all it holds, its read-only folders included."""
    folder = tempfile.mkdtemp(prefix=prefix, dir="/tmp")
    os.chmod(folder, 0o755)
    try:
        yield pathlib.Path(folder)
    finally:
        for root, names, _ in os.walk(folder):
            for name in names:  # a test's read-only folder, which a user other than root cannot empty
                with contextlib.suppress(OSError):
                    os.chmod(os.path.join(root, name), 0o755)
        shutil.rmtree(folder, ignore_errors=True)


def as_other_user(
    command: list[str], public: pathlib.Path, env: dict[str, str] | None = None
) -> tuple[list[str], dict[str, str]]:
    """(command, environment) that run `command` as `USER`, without groups, where the tests run as root (as
    it is where they do not: their user meets the refusals already). The environment is `env` (by default this
    process's, with PYTHONPATH = sys.path: a Python that imports what the tests import) with NUMBA_CACHE_DIR
    a folder in `public` for the other user's runs alone (in a cache root's runs share, numba's folders would be
    root's, which the other user may not write)."""
    if os.geteuid() == 0:
        command = ["setpriv", f"--reuid={USER}", "--regid=nogroup", "--clear-groups", *command]
    numba = public / "numba"
    numba.mkdir(exist_ok=True)
    os.chmod(numba, 0o777)
    base = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path)) if env is None else env
    return command, dict(base, NUMBA_CACHE_DIR=str(numba))
