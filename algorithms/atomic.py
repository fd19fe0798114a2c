"""Safe writes: the one place that makes a file or a folder appear whole under its final name, or not
at all.

A write goes to a temporary name in the target's folder, `.<name>.<host>-<pid>.<8 hex>.part<ext>`
(the extension kept, so drivers that choose a format by it still do; the dot left out on request), and is
renamed over the target
only when everything succeeded:

- GDAL's failures during the write are checked, including those on closing a dataset, which the
  Python bindings print and then swallow (a full disk met while GDAL writes the last tiles on close):
  a GDAL error handler records them in the writing thread, and any CE_Failure recorded fails the write;
- a file is flushed to disk (fsync) before the rename, so a file system that reports a full disk late
  (delayed allocation, NFS, quotas) fails the write here, not after the rename;
- the file system's errors (no permission, no space, quota, read-only, a missing folder) become
  StorageError naming the path, the cause and what to do. `check_destination` runs the same checks
  before a long computation, so a bad output folder fails in a second, not after an hour;
- only a regular file (or nothing) is ever replaced by a file, only a folder (or nothing) by a folder:
  a device node (/dev/full), a FIFO, a socket or a folder in the way is a StorageError, never replaced;
- a format that is several files (a shapefile's .shp, .shx, .dbf, .prj: COMPANIONS) is written as one:
  the companions the driver made beside the temporary name are renamed with it, stale ones of the old
  file removed.

Leftovers of killed runs. A process killed mid-write leaves its temporary name behind. On the first
write into a folder, a process removes the temporary names of that folder whose writer is gone: same
host and no process with that pid, or another host's name older than STALE_SECONDS (a writer on
another machine of a cluster cannot be asked). A live writer's name is never touched. `leftovers`
lists them with their owner and whether they are stale. A folder replaced by `atomic_dir` is swapped
in two renames; a kill between them leaves the old folder as `.<name>.<host>-<pid>.<hex>.old/x`, which
the clean-up puts back."""

import contextlib
import errno
import os
import re
import secrets
import shutil
import socket
import stat
import threading
import time
from typing import Optional

from .errors import StorageError
from .gdal_errors import HeldMessages

#: age (s) after which another host's temporary name counts as stale (its writer cannot be checked)
STALE_SECONDS = 24 * 3600.0
#: this host's name as it appears in temporary names
HOST = re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname().split(".")[0]) or "host"
_NAME = re.compile(
    r"^\.?(?P<name>.+)\.(?P<host>[A-Za-z0-9_]+)-(?P<pid>\d+)\.(?P<tag>[0-9a-f]{8})"
    r"\.(?P<kind>part|old)(?P<rest>.*)$"
)
#: what to do, per errno of a failed write
ADVICE = {
    errno.ENOSPC: "the disk is full: free space there or choose a folder on another disk",
    errno.EDQUOT: "the disk quota is used up: free space or choose a folder on another disk",
    errno.EACCES: "no permission to write there: choose a folder you can write to",
    errno.EPERM: "no permission to write there: choose a folder you can write to",
    errno.EROFS: "the file system is read-only: choose a folder on a writable disk",
    errno.ENOENT: "the folder does not exist and cannot be made: check the path",
    errno.ENOTDIR: "a part of the path is a file, not a folder: check the path",
    errno.EISDIR: "a folder of that name is in the way: choose another name",
    errno.ENAMETOOLONG: "the path is too long: choose a shorter one",
}
#: GDAL/SQLite error texts of a failed write and the errno they stand for
_GDAL_TEXTS = (
    ("no space left", errno.ENOSPC),
    ("disk is full", errno.ENOSPC),
    ("disk full", errno.ENOSPC),
    ("quota", errno.EDQUOT),
    ("permission denied", errno.EACCES),
    # SQLite's "attempt to write a readonly database": a file or folder this user may not write, far more
    # often than a read-only file system (whose own text, "read-only", maps below)
    ("readonly database", errno.EACCES),
    ("read-only", errno.EROFS),
    ("unable to open database file", errno.EACCES),
)
#: texts that can only come from a failed write
_WRITE_TEXTS = ("no space left", "disk is full", "disk full", "quota", "read-only file system", "write error")
#: the files a format writes beside the one named (lower-case extensions), renamed with it by atomic_path
COMPANIONS = {".shp": (".shx", ".dbf", ".prj", ".cpg")}
_cleaned = set()
_cleaned_lock = threading.Lock()


def storage_error(exc, path, what="the output", action=None):
    """StorageError for `exc` (an OSError, or a GDAL/SQLite error text) met while writing `path`: "cannot
    <action>: <cause> (<what to do>)", the action by default "write <what> <path>"."""
    code = getattr(exc, "errno", None)
    text = getattr(exc, "strerror", None) or str(exc)
    if code not in ADVICE:
        low = str(exc).lower()
        code = next((c for key, c in _GDAL_TEXTS if key in low), code)
    advice = ADVICE.get(code, "check the path, the free space and the permissions")
    return StorageError(f"cannot {action or f'write {what} {os.fspath(path)}'}: {text.strip()} ({advice})")


def _io_failure(exc, tmp):
    """Whether `exc`, raised while writing `tmp`, is a failure of that write rather than of the code or of
    reading an input: a full disk, a quota or a read-only file system anywhere in the body; another
    error of the file system only where it names the temporary path."""
    if isinstance(exc, OSError):
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG):
            return True
        return exc.filename is not None and os.fspath(exc.filename).startswith(tmp)
    low = str(exc).lower()
    if isinstance(exc, RuntimeError):
        return any(key in low for key in _WRITE_TEXTS) or (
            os.path.basename(tmp).lower() in low and any(key in low for key, _ in _GDAL_TEXTS)
        )
    return False


def owner_gone(host, pid, age):
    """Whether the writer (host, pid) of a temporary name `age` seconds old has gone: no process `pid` on this
    host, or another host's name older than STALE_SECONDS (module docstring)."""
    if host != HOST:
        return age > STALE_SECONDS
    if int(pid) == os.getpid():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OverflowError):
        return False
    return False


def leftovers(folder):
    """Temporary names of this module in `folder`: a list of dicts (path, target, host, pid, age s, stale)."""
    found = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return found
    now = time.time()
    for entry in entries:
        match = _NAME.match(entry.name)
        if not match:
            continue
        try:
            age = now - entry.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        found.append(
            {
                "path": entry.path,
                "target": os.path.join(folder, match["name"] + match["rest"]),
                "kind": match["kind"],
                "host": match["host"],
                "pid": int(match["pid"]),
                "age": age,
                "stale": owner_gone(match["host"], match["pid"], age),
            }
        )
    return found


def clean_leftovers(folder):
    """Remove the stale temporary names of `folder` (a folder swapped out by a killed `atomic_dir` is put
    back where its target is missing); returns the paths removed or restored."""
    done = []
    for item in leftovers(folder):
        if not item["stale"]:
            continue
        path = item["path"]
        try:
            inner = os.path.join(path, "x")
            if item["kind"] == "old" and os.path.isdir(inner) and not os.path.lexists(item["target"]):
                os.rename(inner, item["target"])
            if os.path.isdir(path) and not os.path.islink(path):
                shutil.rmtree(path)
            else:
                os.unlink(path)
            done.append(path)
        except OSError:
            continue
    return done


def _clean_once(folder):
    with _cleaned_lock:
        if folder in _cleaned:
            return
        _cleaned.add(folder)
    clean_leftovers(folder)


def _temporary_name(path, kind="part", hidden=True):
    folder = os.path.dirname(os.path.abspath(path))
    base, ext = os.path.splitext(os.path.basename(path))
    name = f"{base}.{HOST}-{os.getpid()}.{secrets.token_hex(4)}.{kind}{ext}"
    return os.path.join(folder, "." + name if hidden else name)


def _folder(path, what):
    """The target's folder, made if missing; StorageError if it cannot be made."""
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    try:
        os.makedirs(folder, exist_ok=True)
    except FileExistsError:  # a part of the path is a file
        raise storage_error(OSError(errno.ENOTDIR, "Not a directory"), path, what) from None
    except OSError as exc:
        raise storage_error(exc, path, what) from None
    return folder


def companions(path) -> list:
    """The files written beside `path` with it (COMPANIONS: a shapefile's .shx, .dbf, ...)."""
    base, ext = os.path.splitext(os.fspath(path))
    return [base + extra for extra in COMPANIONS.get(ext.lower(), ())]


def node_kind(path) -> Optional[str]:
    """What `path` is where it is neither missing nor a regular file: "a folder", "a device", "a FIFO" or "a
    socket" (a symbolic link is followed); None for a regular file or nothing."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    for test, kind in (
        (stat.S_ISREG, None),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return kind
    return "a device"


def refuse_non_file(path, what: str = "the output") -> None:
    """StorageError where `path` exists and is not a regular file (node_kind): a file is never written over a
    folder, a device node, a FIFO or a socket."""
    kind = node_kind(path)
    if kind == "a folder":
        raise storage_error(OSError(errno.EISDIR, "a folder has that name"), path, what)
    if kind is not None:
        raise StorageError(
            f"cannot write {what} {os.fspath(path)}: it is {kind}, not a regular file, and is never "
            "replaced: give the path of a file (nothing was written)"
        )


def refuse_non_folder(path, what: str = "the output folder") -> None:
    """StorageError where `path` exists and is not a folder: only a folder is replaced by a folder, and a
    folder is written into only where it is one."""
    if os.path.exists(path) and not os.path.isdir(path):
        raise StorageError(
            f"cannot write {what} {os.fspath(path)}: {node_kind(path) or 'a file'} has that name, and "
            "only a folder is replaced by the folder written there: choose another name (nothing was "
            "written)"
        )


def check_destination(path, what="the output"):
    """Fail now, with a StorageError that says what to do, where `path` cannot be written: its folder
    cannot be made, is not writable (a probe file is created and removed), or something that is not a
    regular file is in the way (a folder, a device, a FIFO, a socket: never replaced)."""
    path = os.fspath(path)
    folder = _folder(path, what)
    refuse_non_file(path, what)
    probe = _temporary_name(path)
    try:
        with open(probe, "wb"):
            pass
    except OSError as exc:
        raise storage_error(exc, path, what) from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(probe)
    return folder


def close_dataset(ds):
    """Close a GDAL or OGR dataset now and raise its failure here (RuntimeError with exceptions on), where the
    caller can catch it: GDAL writes cached blocks, overviews and headers on close, and the Python bindings of
    GDAL < 3.8 report a failed close made by reference counting only as an "Exception ignored" print. The
    dataset must not be used afterwards."""
    if ds is None:
        return
    if hasattr(ds, "Destroy"):  # ogr.DataSource
        ds.Destroy()
        return
    try:
        type(ds).__swig_destroy__(ds)
    finally:
        ds.thisown = 0


@contextlib.contextmanager
def closing(ds):
    """Yield the GDAL/OGR dataset `ds` and close it when the block ends (`close_dataset`), also when the block
    fails (that close's own failure then gives way to the block's)."""
    try:
        yield ds
    except BaseException:
        with contextlib.suppress(RuntimeError):
            close_dataset(ds)
        raise
    close_dataset(ds)


def _fsync(path):
    if os.path.isdir(path):
        for root, _dirs, files in os.walk(path):
            for name in files:
                _fsync(os.path.join(root, name))
        return
    if os.path.isfile(path):
        with open(path, "rb+") as f:
            os.fsync(f.fileno())


def _cause(messages):
    """The message of a failed GDAL write that names its cause (a full disk, a permission), else the first:
    one failure makes GDAL report a dozen follow-ups."""
    return next((m for m in messages if any(key in m.lower() for key, _ in _GDAL_TEXTS)), messages[0])


@contextlib.contextmanager
def _guarded(path, what, tmp):
    """Run the body of a write of `tmp` for `path`: GDAL failures recorded, I/O errors translated, the
    result flushed (module docstring)."""
    gdal_failures = HeldMessages()
    try:
        with gdal_failures:
            yield
        if gdal_failures.failures:
            raise storage_error(RuntimeError(_cause(gdal_failures.failures)), path, what)
        _fsync(tmp)
    except StorageError:
        raise
    except (OSError, RuntimeError) as exc:
        if _io_failure(exc, tmp) or any(_io_failure(RuntimeError(m), tmp) for m in gdal_failures.failures):
            cause = RuntimeError(_cause(gdal_failures.failures + [str(exc)])) if isinstance(exc, RuntimeError) else exc
            raise storage_error(cause, path, what) from exc
        raise


@contextlib.contextmanager
def atomic_path(path, what="the output", hidden=True):
    """Yield a temporary path in the target's folder; when the body succeeds, rename it to `path`
    (module docstring). GDAL datasets written to it must be closed inside the body. `hidden=False` for a
    writer that names something after the file's base name, which a leading dot leaves empty (QGIS names the
    .qgs inside a .qgz so)."""
    path = os.fspath(path)
    folder = _folder(path, what)
    _clean_once(folder)
    refuse_non_file(path, what)
    tmp = _temporary_name(path, hidden=hidden)
    try:
        with _guarded(path, what, tmp):
            yield tmp
        refuse_non_file(path, what)  # again: something may have taken the name meanwhile
        try:
            for made, target in zip(companions(tmp), companions(path)):
                if os.path.exists(made):
                    os.replace(made, target)
                elif os.path.lexists(target):  # the old file's, which would describe the new one wrongly
                    os.unlink(target)
            os.replace(tmp, path)
        except OSError as exc:
            raise storage_error(exc, path, what) from exc
    finally:
        for leftover in (
            tmp,
            tmp + ".aux.xml",
            tmp + ".ovr",
            tmp + "-journal",
            tmp + "-wal",
            tmp + "-shm",
            *companions(tmp),
        ):
            with contextlib.suppress(OSError):
                os.unlink(leftover)


def write_text(path, text, what="the output"):
    """Write `text` to `path` atomically (UTF-8)."""
    with atomic_path(path, what) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)


class _Writer:
    """A file's write method alone: numpy writes an array through it in chunks, and a full disk raises the
    OSError with its errno (ndarray.tofile, which numpy uses on real files, loses it)."""

    def __init__(self, f):
        self.write = f.write


def save_array(path, array, what="an intermediate file"):
    """numpy.save of `array` to `path` (.npy) atomically; a failed write is the StorageError of `what`."""
    import numpy as np

    with atomic_path(path, what) as tmp, open(tmp, "wb") as f:
        np.save(_Writer(f), array)
    return path


def append_bytes(path, data, what="an intermediate file"):
    """Append `data` (bytes-like) to the file `path`; a failed write is the StorageError of `what`."""
    try:
        with open(path, "ab") as f:
            f.write(data)
    except OSError as exc:
        raise storage_error(exc, path, what) from None


def _temporary_dir(path, what):
    """A new temporary folder beside `path` (its folder made and cleaned of stale leftovers first)."""
    _clean_once(_folder(path, what))
    tmp = _temporary_name(path)
    try:
        os.mkdir(tmp)
    except OSError as exc:
        raise storage_error(exc, path, what) from None
    return tmp


@contextlib.contextmanager
def work_dir(path, what="the intermediate files"):
    """Yield a hidden temporary folder beside `path` for a step's intermediate files (what the tile tasks
    write, where every worker sees the output's file system), removed when the body ends; after a kill, the
    next write into that folder removes it once its writer has gone (clean_leftovers)."""
    tmp = _temporary_dir(path, what)
    try:
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


@contextlib.contextmanager
def atomic_dir(path, what="the output folder"):
    """Yield a temporary folder beside `path`; when the body succeeds it replaces `path` as a whole. A file,
    a device, a FIFO or a socket at `path` is a StorageError before the body runs (only a folder is replaced
    by a folder)."""
    path = os.path.abspath(os.fspath(path))
    refuse_non_folder(path, what)
    tmp = _temporary_dir(path, what)
    try:
        with _guarded(path, what, tmp):
            yield tmp
        try:
            if os.path.exists(path):
                old = _temporary_name(path, "old")
                os.mkdir(old)
                os.rename(path, os.path.join(old, "x"))
                os.rename(tmp, path)
                shutil.rmtree(old)
            else:
                os.rename(tmp, path)
        except OSError as exc:
            raise storage_error(exc, path, what) from exc
    finally:
        if os.path.exists(tmp):
            shutil.rmtree(tmp, ignore_errors=True)
