"""The real Pleiades triplet's surface chain at STEP 1 through qgis_process: this version against the version
before the tiled pipeline (issue 21), in the same run.

The chain, each step one `qgis_process run`, with 2 threads where the version has the parameter (the
earlier one had none for intersectpoints and interpolatedem): createblock (the three crops of
pleiades_triplet in benchutil.SHARED_DATA, RPC in the GeoTIFFs), matchpoints (region growing, automatic
seeds, a node every pixel), intersectpoints, interpolatedem (0.5 m cells) and orthorectify (img_02 on
that DEM). The earlier version is BASELINE, checked out as a git worktree under build/ and loaded as the
plugin of its own QGIS profile; both run on the same machine one after the other. Rows: time and peak
memory (the sum of the processes' VmHWM) per step, the point counts, and the ratios of this version's
times to the earlier one's. Issue 22 measured the chain without orthorectify at 495 s before.

    python -m tests.benchmarks.bench_pleiades_chain
"""

import pathlib
import subprocess
import tempfile

from tests.benchmarks.bench_chain_memory import measured
from tests.benchmarks.benchutil import SHARED_DATA
from tests.helpers.qgis_process_profile import QGIS_PROCESS, REPO, qgis_process_env

DATA = SHARED_DATA / "pleiades_triplet"
BASELINE = "cdd5892b6c38048d548363c9713d8c4cf0d4bba0"  # main before the execution layer (2c637c4)
WORKERS = 2


def baseline_tree():
    """The BASELINE checkout under build/ (made once)."""
    tree = REPO / "build" / f"baseline-{BASELINE[:7]}"
    if not tree.exists():
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(tree), BASELINE],
            check=True,
            capture_output=True,
        )
    return tree


def steps(out, tiled):
    """The chain's (name, qgis_process arguments), writing into `out`; `tiled`: this version's parameters
    (EXECUTION, WORKERS) rather than the baseline's (WORKERS, THREADS)."""
    block = out / "block.gpkg"
    workers = ["EXECUTION=0", f"WORKERS={WORKERS}"] if tiled else []
    return [
        (
            "createblock",
            [
                "pushbroom:createblock",
                "--",
                *(f"IMAGES={DATA / f'img_0{i}.tif'}" for i in (1, 2, 3)),
                f"OUTPUT={block}",
            ],
        ),
        (
            "matchpoints",
            ["pushbroom:matchpoints", "--", f"BLOCK={block}", "STEP=1", *(workers or [f"WORKERS={WORKERS}"])],
        ),
        (
            "intersectpoints",
            ["pushbroom:intersectpoints", "--", f"BLOCK={block}", "POINTS=0", *workers, f"OUTPUT={out / 'points.las'}"],
        ),
        (
            "interpolatedem",
            [
                "pushbroom:interpolatedem",
                "--",
                f"INPUT={out / 'points.las'}",
                "CELL=0.5",
                *workers,
                f"OUTPUT={out / 'dem.tif'}",
            ],
        ),
        (
            "orthorectify",
            [
                "pushbroom:orthorectify",
                "--",
                f"BLOCK={block}",
                "IMAGE_NAME=img_02",
                f"DEM={out / 'dem.tif'}",
                *(workers or [f"THREADS={WORKERS}"]),
                f"OUTPUT={out / 'ortho.tif'}",
            ],
        ),
    ]


def chain(plugin, label, tiled):
    """Rows of the chain with the plugin in `plugin`."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        env = qgis_process_env(tmp / "profile", plugin)
        for name, args in steps(tmp, tiled):
            seconds, peak, processes, output = measured([QGIS_PROCESS, "run"] + args, env)
            print(f"  {label} {name}: {seconds:.1f} s, {peak:.0f} MB", flush=True)
            count = [line.split()[-1] for line in output.splitlines() if line.startswith("COUNT:")]
            rows.append(
                {
                    "version": label,
                    "step": name,
                    "points": count[0] if count else "",
                    "seconds": seconds,
                    "peak MB": peak,
                    "processes": processes,
                }
            )
    seconds = [r["seconds"] for r in rows]
    return rows + [
        {"version": label, "step": "total", "seconds": sum(seconds), "peak MB": max(r["peak MB"] for r in rows)},
        {"version": label, "step": "total without orthorectify (issue 22's chain)", "seconds": sum(seconds[:-1])},
    ]


def run():
    if not DATA.is_dir():
        return [{"version": "", "step": f"skipped: {DATA} is absent"}]
    before = chain(baseline_tree(), f"before ({BASELINE[:7]})", tiled=False)
    after = chain(REPO, "this version", tiled=True)
    ratios = [
        {"version": "this / before", "step": a["step"], "seconds": f"x {a['seconds'] / b['seconds']:.3f}"}
        for a, b in zip(after, before)
    ]
    return before + after + ratios


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    print(markdown_table(run()))
