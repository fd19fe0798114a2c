"""kill -9 of a local worker process while pushbroom:matchpoints runs on two of them (issue 36: the step hung for
ever, its main thread blocked in a pipe write): region growing and dense matching on the small triplet's block,
in a process of their own as under qgis_process, fail rather than hang, naming the worker, and the block keeps
what it held, byte for byte. Small tiles give each round many tasks, so the kill falls inside a round whatever
the machine's speed. Region growing runs at a 2 px step: at 4 px a round's work was short enough that the kill once
fell after its last task (exit code 0, nothing printed: the step rightly finished, as no task was lost)."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest

from tests.helpers.fingerprint import fingerprint
from tests.helpers.processes import cpu_seconds, worker_processes

#: s of CPU a worker process has used when it is killed: past its start (imports), inside its tasks
BUSY_CPU_S = 4.0


#: the step, as a user's process runs it: prints the ExecutionError's message as JSON
STEP = """
import json, sys
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.errors import ExecutionError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowingSettings
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points
if __name__ == "__main__":
    settings = {"region_growing": RegionGrowingSettings(grow=GrowParams(step=2, tile=64)),
                "dense": DenseParams(tile=64)}[sys.argv[2]]
    params = MatchParams(strategy=sys.argv[2], settings=settings, execution=Execution("processes", 2))
    try:
        match_block_points(sys.argv[1], params)
    except ExecutionError as exc:
        print(json.dumps(str(exc)))
"""


def kill_a_busy_worker(step):
    """SIGKILL the first worker process of the process `step` that has used BUSY_CPU_S of CPU: its pid, or None
    if `step` ended first."""
    while step.poll() is None:
        for pid in worker_processes(step.pid):
            if cpu_seconds(pid) >= BUSY_CPU_S:
                os.kill(pid, signal.SIGKILL)
                return pid
        time.sleep(0.05)
    return None


@pytest.mark.slow
@pytest.mark.parametrize("strategy", ["region_growing", "dense"])
def test_a_worker_killed_during_matchpoints_fails_it_and_keeps_the_block(small_scene_block, tmp_path, strategy):
    path = str(tmp_path / "block.gpkg")
    shutil.copy(small_scene_block[0], path)
    before = fingerprint(tmp_path)
    script = tmp_path / "step.py"
    script.write_text(STEP)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    errors = tmp_path.parent / f"{tmp_path.name}-stderr.txt"  # a file, not a pipe: the workers write to it too
    with (
        open(errors, "w") as stderr,
        subprocess.Popen(
            [sys.executable, str(script), path, strategy], stdout=subprocess.PIPE, stderr=stderr, text=True, env=env
        ) as step,
    ):
        try:
            killed = kill_a_busy_worker(step)
            # a hang (the issue) fails here: the step stops within the pool's GRACE (10 s) of the kill
            out, _ = step.communicate(timeout=120)
        finally:
            step.kill()  # a hung step is not left behind (a no-op once it ended)
    assert killed, "no worker was killed: the step ended first"
    # the step's own end where it printed no ExecutionError (seen once in CI, not reproduced: the record for next time)
    assert out.strip(), f"the step printed no error: exit code {step.returncode}, stderr {errors.read_text()[-3000:]!r}"
    assert f"worker process {killed} died (killed by SIGKILL" in json.loads(out)
    script.unlink()
    assert fingerprint(tmp_path) == before  # the block as it was: no points, no layer, no folder
