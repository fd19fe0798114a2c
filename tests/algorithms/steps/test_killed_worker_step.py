"""kill -9 of a local worker process while pushbroom:matchpoints runs on two of them (issue 36: the step hung for
ever, its main thread blocked in a pipe write): region growing and dense matching on the small triplet's block,
in a process of their own as under qgis_process, fail within seconds, naming the worker, and the block keeps
what it held, byte for byte. Small tiles give each round many tasks, so the kill falls inside a round whatever
the machine's speed."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from tests.helpers.fingerprint import fingerprint
from tests.helpers.processes import command_line, descendants

#: s of CPU a worker process has used when it is killed: past its start (imports), inside its tasks
BUSY_CPU_S = 4.0


def cpu_seconds(pid):
    """User + system CPU time of process `pid` (s; 0 where it has gone)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="utf-8") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


#: the step, as a user's process runs it: prints the ExecutionError's message as JSON
STEP = """
import json, sys
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.errors import ExecutionError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points
if __name__ == "__main__":
    params = MatchParams(strategy=sys.argv[2], grow=GrowParams(step=4, tile=64), dense=DenseParams(tile=64),
                         execution=Execution("processes", 2))
    try:
        match_block_points(sys.argv[1], params)
    except ExecutionError as exc:
        print(json.dumps(str(exc)))
"""


def kill_a_busy_worker(step):
    """SIGKILL the first worker process of the process `step` that has used BUSY_CPU_S of CPU: (its pid, the
    time of the kill), or None if `step` ended first."""
    while step.poll() is None:
        for pid in descendants(step.pid):
            if "spawn_main" in command_line(pid) and cpu_seconds(pid) >= BUSY_CPU_S:
                os.kill(pid, signal.SIGKILL)
                return pid, time.monotonic()
        time.sleep(0.05)
    return None


@pytest.mark.slow
@pytest.mark.parametrize("strategy", ["region_growing", "dense"])
def test_a_worker_killed_during_matchpoints_fails_it_within_seconds(small_scene_block, tmp_path, strategy):
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    before = fingerprint(tmp_path)
    script = tmp_path / "step.py"
    script.write_text(STEP)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    with subprocess.Popen([sys.executable, str(script), path, strategy], stdout=subprocess.PIPE, text=True,
                          env=env) as step:
        killed = kill_a_busy_worker(step)
        out, _ = step.communicate(timeout=300)
        ended = time.monotonic()
    assert killed, "no worker was killed: the step ended first"
    assert ended - killed[1] < 20                       # seconds, not a hang (the pool's GRACE is 10 s)
    assert f"worker process {killed[0]} died (killed by SIGKILL" in json.loads(out)
    script.unlink()
    assert fingerprint(tmp_path) == before              # the block as it was: no points, no layer, no folder
