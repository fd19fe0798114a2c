"""The stored points of the three matching strategies against a record made before the matching room was
rebuilt (issue 38): region growing, dense (with MPGC) and coarse-to-fine, on the small simulated triplet and its
pair, each over several tiles. A refactoring of the matching must leave them as they were; a change of the science
must rewrite the record on purpose, saying why in its commit:
`PUSHBROOM_RECORD_GOLDEN=1 pytest -p no:xdist tests/algorithms/steps/test_matching_golden.py`.

Byte for byte on the machine the record was made on only: another CPU changes the last bits of some values (numba
compiles for the host CPU; numpy, OpenBLAS and the semi-global matcher's C++ may pick CPU-specific kernels; which of
them changed the bytes between the Intel and the AMD machine of 2026-11-29 is not known: neither NUMBA_CPU_NAME nor
OPENBLAS_CORETYPE did), and with them, now and then, a point's fate at a threshold. The record holds, per case:
- the counts of points and observations, within COUNT_TOLERANCE of them on every machine (the dense triplet's
  differed by 2 of 32 523 points between the two machines);
- a summary of every numeric field of both arrays but the ids: the count of its finite values, their mean,
  standard deviation, mean weighted by the point id (values moved to other points change it) and mean fractional
  part (a sub-pixel shift changes it), on every machine within the tolerances of assert_close_summaries, which allow
  a few points' fates. A change of the science that shifts, drops or moves points moves them by far more;
  zero-mean noise added to every position does not, which only the bytes catch;
- the SHA-256 of both arrays' bytes under the fingerprint of the machine that recorded them (machine_fingerprint),
  compared where the fingerprint is the same. Elsewhere the figures say that only the summaries were compared."""

import hashlib
import json
import os
import shutil

import numpy as np
import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowingSettings
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points

RECORD = os.path.join(os.path.dirname(__file__), "..", "..", "golden", "matching.json")
#: the id fields, numbered 1 ... n (their counts are compared, not their moments)
IDS = ("id", "point_id")
#: tolerance of the summaries, and of the counts (relative; module docstring)
TOLERANCE, COUNT_TOLERANCE = 1e-4, 5e-4
NAMES = {"triplet": ("HRG", "HRS1", "HRS2"), "pair": ("HRG", "HRS1")}
#: each strategy's settings: small tiles, so that every case runs several of them
CASES = {
    "region_growing": dict(
        strategy="region_growing", settings=RegionGrowingSettings(grow=GrowParams(step=6, tile=256))
    ),
    "dense": dict(strategy="dense", settings=DenseParams(step=3, tile=256, mpgc=True)),
    "coarse_to_fine": dict(strategy="coarse_to_fine", settings=CoarseToFineParams(tile=512, grid=8)),
}


@pytest.fixture(scope="module")
def blocks(simulated, tmp_path_factory):
    """{'triplet' | 'pair': a template block of the error-free small scene} and its DSM's height range +- 30 m."""
    paths = simulated(SceneConfig.small(error_scale=0.0))
    lo, hi = read_dem(paths["dsm"]).height_range
    folder = tmp_path_factory.mktemp("golden")
    made = {}
    for kind, names in NAMES.items():
        made[kind] = str(folder / f"{kind}.gpkg")
        Block.create(
            made[kind], Block.open_images([paths["images"][n]["imagery"] for n in names]), height=(lo + hi) / 2
        )
    return made, (lo - 30.0, hi + 30.0)


def machine_fingerprint():
    """What decides the last bits of the results: the host CPU as LLVM names it and its features, the CPU numba
    compiles for where NUMBA_CPU_NAME and NUMBA_CPU_FEATURES say, numba's, numpy's and scipy's versions (a short
    SHA-256)."""
    import llvmlite.binding
    import numba
    import numpy
    import scipy
    from numba.core import config

    text = " ".join(
        [
            llvmlite.binding.get_host_cpu_name(),
            llvmlite.binding.get_host_cpu_features().flatten(),
            str(config.CPU_NAME),
            str(config.CPU_FEATURES),
            numba.__version__,
            numpy.__version__,
            scipy.__version__,
        ]
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def summary(a, ids):
    """Per numeric field of the structured array `a` (rows of the point `ids`): [count of finite values, mean, standard
    deviation, mean weighted by the id, mean fractional part]; None for the moments where none is finite. The ids
    themselves (1 ... n) have no moments: one point more or less shifts them all."""
    out = {}
    for name in a.dtype.names:
        if name in IDS:
            continue
        v = a[name].astype(float)
        ok = np.isfinite(v)
        if not ok.any():
            out[name] = [0, None, None, None, None]
            continue
        w = ids[ok].astype(float)
        v = v[ok]
        out[name] = [
            int(ok.sum()),
            float(v.mean()),
            float(v.std()),
            float((v * w).sum() / w.sum()),
            float((v % 1.0).mean()),
        ]
    return out


def digest(block):
    """The block's mass points as the record holds them (module docstring), with this machine's bytes."""
    mass = Block(block).points()
    arrays = {
        "points": (mass.points, mass.points["id"]),
        "observations": (mass.observations, mass.observations["point_id"]),
    }
    return {
        "counts": {k: len(a) for k, (a, _) in arrays.items()},
        "summary": {k: summary(a, ids) for k, (a, ids) in arrays.items()},
        "bytes": {machine_fingerprint(): {k: hashlib.sha256(a.tobytes()).hexdigest() for k, (a, _) in arrays.items()}},
    }


def assert_close_summaries(found, recorded, case):
    """Each field's summary within its tolerance (module docstring): the count within COUNT_TOLERANCE; the moments
    within TOLERANCE of the field's scale plus what `flips` points' fates can move them (each at most about 3 standard
    deviations over n); the fractional part within TOLERANCE plus flips / n."""
    for array, fields in recorded.items():
        for name, want in fields.items():
            got = found[array][name]
            message = f"{case}: {array}.{name} summary {got}, recorded {want}"
            n = want[0]
            assert abs(got[0] - n) <= COUNT_TOLERANCE * n, message
            if want[1] is None:
                continue
            flips = max(COUNT_TOLERANCE * n, 2.0)
            moment = TOLERANCE * max(abs(want[1]), want[2]) + 3.0 * want[2] * flips / n
            assert all(abs(g - w) <= moment for g, w in zip(got[1:4], want[1:4])), message
            assert abs(got[4] - want[4]) <= TOLERANCE + flips / n, message


@pytest.mark.slow
@pytest.mark.parametrize("kind", NAMES)
@pytest.mark.parametrize("strategy", CASES)
def test_stored_points_are_as_recorded(blocks, strategy, kind, tmp_path, figures):
    templates, (lo, hi) = blocks
    path = str(tmp_path / "block.gpkg")
    shutil.copy(templates[kind], path)
    match_block_points(path, MatchParams(min_height=lo, max_height=hi, **CASES[strategy]))
    found, case = digest(path), f"{strategy} {kind}"
    with open(RECORD) as f:
        record = json.load(f)
    if os.environ.get("PUSHBROOM_RECORD_GOLDEN"):
        record[case] = found
        with open(RECORD, "w") as f:
            json.dump(record, f, indent=1, sort_keys=True)
            f.write("\n")
    want = record[case]
    counts = f"{case}: counts {found['counts']}, recorded {want['counts']}"
    assert all(abs(found["counts"][k] - n) <= COUNT_TOLERANCE * n for k, n in want["counts"].items()), counts
    assert_close_summaries(found["summary"], want["summary"], case)
    machine = machine_fingerprint()
    if machine in want["bytes"]:
        assert found["bytes"][machine] == want["bytes"][machine], f"{case}: the bytes differ on the recording machine"
    else:
        figures.report(
            f"golden {case}: recorded on another machine, summaries compared (bytes not)", len(want["bytes"]), "records"
        )
