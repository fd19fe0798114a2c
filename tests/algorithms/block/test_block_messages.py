"""SQLite's failures said in Pushbroom's words, with the right advice (issue 36): an exclusive lock names the
program that holds it; a file that is no whole block (an SQLite database, a file cut short) says so; a block
file or folder the user may not write is refused before any work, saying by whom it may be written."""

import json
import os
import re
import shutil
import sqlite3
import subprocess
import sys

import pytest

from pushbroom.algorithms.block import Block, schema
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.errors import InputError, StorageError
from tests.helpers.other_user import as_other_user, public_folder


@pytest.fixture
def block(tmp_path):
    path = tmp_path / "b.gpkg"
    create_schema(path).Destroy()
    return str(path)


HOLD = """
import sqlite3, sys
db = sqlite3.connect(sys.argv[1], isolation_level=None)
db.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
sys.stdin.read()
"""


def test_an_exclusive_lock_names_the_program_that_holds_it(block, monkeypatch):
    monkeypatch.setattr(schema, "BUSY_TIMEOUT_MS", 300)
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, block], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(StorageError) as err:
            Block(block).info()
    finally:
        holder.stdin.close()
        holder.wait()
    message = str(err.value)
    # the lock, the program and its process (Linux's /proc/locks), what to do; not SQLite's "check the free space"
    assert re.search(rf"another program \([^,]+, process {holder.pid}\) holds an exclusive lock on it", message)
    assert "run this step again" in message and "free space" not in message
    assert Block(block).info()["format_version"] == "1"  # readable again once the program has let go


def test_files_that_are_no_whole_block_are_named(block, tmp_path, capfd):
    plain = tmp_path / "plain.gpkg"
    with sqlite3.connect(plain) as db:
        db.execute("CREATE TABLE t (a)")
    with pytest.raises(
        InputError,
        match=r"plain.gpkg is not a Pushbroom block \(an SQLite database, but not a "
        r"GeoPackage\)",
    ):
        Block(plain).info()
    assert "bad application_id" not in capfd.readouterr().err  # GDAL's own warning of it is not printed
    data = open(block, "rb").read()
    half = rf"the file holds {len(data) // 2} bytes, its header records .* \({len(data)}\)"
    for size, fact in ((len(data) // 2, half), (50, "the file holds 50 bytes, less than the 100 of an SQLite header")):
        cut = tmp_path / f"cut{size}.gpkg"
        cut.write_bytes(data[:size])
        # damaged, how, and what to do: not SQLite's "database disk image is malformed" nor "not a block"
        with pytest.raises(InputError, match=rf"the block {cut} is damaged \({fact}\): .* Restore it from a copy"):
            Block(cut).info()


AS_USER = """
import json, sys
from pushbroom.algorithms.steps.adjust_block import AdjustParams, adjust_block
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points
from pushbroom.algorithms.steps.block_tie_points import TieParams, select_block_tie_points
from pushbroom.algorithms.steps.point_files import ImportParams, import_points
steps = {"bundleadjust": lambda path: adjust_block(path, AdjustParams()),
         "importpoints": lambda path: import_points(path, "points.csv", ImportParams()),
         "matchpoints": lambda path: match_block_points(path, MatchParams()),
         "selecttiepoints": lambda path: select_block_tie_points(path, TieParams())}
messages = {}
for path in sys.argv[1:]:
    for name, step in steps.items():
        try:
            step(path)
        except Exception as exc:
            messages[f"{name} {path}"] = str(exc)
print(json.dumps(messages))
"""


def test_a_block_the_user_may_not_write_is_refused_before_any_work(block):
    """A read-only block file; a writable block file in a read-only folder, where SQLite cannot create its
    journal (before: "is not a Pushbroom block", and "attempt to write a readonly database" after the adjustment):
    every step that stores into the block refuses it first, by its entry point, as an unprivileged user."""
    with public_folder("pushbroom-msgs-") as public:
        for name, file_mode, folder_mode in (("file", 0o444, 0o755), ("folder", 0o666, 0o555)):
            (public / name).mkdir()
            shutil.copy(block, public / name / "b.gpkg")
            os.chmod(public / name / "b.gpkg", file_mode)
            os.chmod(public / name, folder_mode)
        paths = [str(public / name / "b.gpkg") for name in ("file", "folder")]
        command, env = as_other_user([sys.executable, "-c", AS_USER, *paths], public)
        result = subprocess.run(command, capture_output=True, text=True, env=env, cwd=public, check=True)
    messages = json.loads(result.stdout)
    assert len(messages) == 8, messages
    for step in ("bundleadjust", "importpoints", "matchpoints", "selecttiepoints"):
        file_message, folder_message = messages[f"{step} {paths[0]}"], messages[f"{step} {paths[1]}"]
        assert "the block file is not writable by you (user " in file_message
        assert "it belongs to root, permissions -r--r--r--" in file_message or os.geteuid() != 0  # root's file
        assert f"its folder {os.path.dirname(paths[1])} is not writable by you" in folder_message
        assert "SQLite must create a journal there (b.gpkg-journal)" in folder_message
        assert all("nothing was stored" in m for m in (file_message, folder_message))
    assert "GDAL" not in result.stderr and "Warning" not in result.stderr  # no GDAL line before them
