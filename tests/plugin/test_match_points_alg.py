"""pushbroom:matchpoints and pushbroom:selecttiepoints on a small simulated SPOT-5 triplet."""

import csv
import os
import re
import subprocess

import numpy as np
import pytest
from osgeo import gdal
from qgis import processing
from qgis.core import QgsProcessingContext, QgsProcessingException, QgsProcessingFeedback, QgsVectorLayer

import pushbroom
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.crs import reproject, srs as srs_of, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching.points import DENSE, REFINED
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.simulation.terrain import BARE, CLASSES, CROPS
from pushbroom.algorithms.surface.local_spread import local_metres
from pushbroom.algorithms.surface.outlier_filter import mean_distances, threshold
from pushbroom.algorithms.surface.pointcloud import laspy_module
from pushbroom.algorithms.task_runtime import BACKENDS
from tests.helpers.dask_cluster import REPO, Cluster, readme_commands, readme_shell
from tests.helpers.qgis_process_profile import QGIS_PROCESS, openblas, qgis_process_env


@pytest.fixture(scope="module")
def triplet(simulated, tmp_path_factory):
    """A 3 x 3 km HRG/HRS1/HRS2 block (supplied orientation = truth) and its DSM height range."""
    folder = tmp_path_factory.mktemp("triplet")
    paths = simulated(SceneConfig.small(error_scale=0.0))
    dsm = gdal.Open(paths["dsm"]).ReadAsArray()
    lo, hi = float(np.nanmin(dsm)), float(np.nanmax(dsm))
    images = Block.open_images([paths["images"][n]["imagery"] for n in ("HRS2", "HRG", "HRS1")])
    return {"images": images, "range": (lo - 30.0, hi + 30.0), "folder": folder, "paths": paths}


def make_block(triplet, name, names):
    path = triplet["folder"] / name
    Block.create(
        path, [i for i in triplet["images"] if i[0] in names], height=sum(triplet["range"]) / 2, overwrite=True
    )
    return str(path)


def test_match_three_images_then_select_tie_points(pushbroom_provider, triplet, tmp_path, log):
    path = make_block(triplet, "three.gpkg", ("HRG", "HRS1", "HRS2"))
    lo, hi = triplet["range"]
    context, feedback = QgsProcessingContext(), QgsProcessingFeedback()
    result = processing.run(
        "pushbroom:matchpoints",
        {"BLOCK": path, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 6, "SUMMARY": str(tmp_path / "summary.csv")},
        context=context,
        feedback=feedback,
    )
    mass = Block(path).points()
    counts = mass.group_counts()
    assert counts[3] > 100, counts  # most points are three-ray (Kornus et al. 2006, Table 1)
    assert counts[3] > counts[1] and counts[3] > counts[2]
    assert np.count_nonzero(mass.points["flags"] & REFINED) > 0.9 * counts[3]  # MPGC refinement, the default
    ids = {r["name"]: r["id"] for r in Block(path).images()}
    assert mass.stats["images"] == [ids["HRG"], ids["HRS1"], ids["HRS2"]]  # ordered by name, not block
    assert Block(path).info()["mass_points_count"] == str(len(mass))
    layer = QgsVectorLayer(result["POINTS"], "mass", "ogr")
    assert layer.isValid() and layer.featureCount() == len(mass)
    assert layer.crs().authid() == "EPSG:4326"
    assert {f.name() for f in layer.fields()} >= {"id", "group", "rho"}
    rows = list(csv.reader(open(result["SUMMARY"])))
    assert rows[0] == ["item", "value"] and int(rows[1][1]) == counts[1]
    assert result["POINTS"] in context.layersToLoadOnCompletion()

    tie = processing.run("pushbroom:selecttiepoints", {"BLOCK": path, "CELL": 100}, context=context)
    tie_points = Block(path).points("tie_points")
    assert 0 < len(tie_points) < len(mass)
    col, row = tie_points.coordinates(ids["HRG"])
    cells = np.floor(row / 100) * 1000 + np.floor(col / 100)
    assert len(np.unique(cells)) == len(tie_points)
    layer = QgsVectorLayer(tie["TIE_POINTS"], "tie", "ogr")
    assert layer.isValid() and layer.featureCount() == len(tie_points)

    # the tie points as the only seeds: tiles with a tie point grow as from automatic seeds
    feedback = log
    processing.run(
        "pushbroom:matchpoints",
        {"BLOCK": path, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 6, "SEEDS": 1},
        context=context,
        feedback=feedback,
    )
    again = Block(path).points()
    assert again.group_counts()[3] > 0.9 * counts[3], (again.group_counts(), counts)
    assert any("seeds from the given points" in m for m in feedback.messages)
    processing.run(
        "pushbroom:matchpoints",
        {"BLOCK": path, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 6, "SEEDS": 2},
        context=context,
    )
    assert Block(path).points().group_counts()[3] >= 0.99 * counts[3]  # both: at least the automatic run
    processing.run(
        "pushbroom:matchpoints",
        {"BLOCK": path, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 6, "MPGC_REFINE": False},
        context=context,
    )
    plain = Block(path).points()
    assert plain.group_counts() == counts and not np.any(plain.points["flags"] & REFINED)
    # block image ids in name order (HRS2 1, HRG 2, HRS1 3): the refined positions went to their own images
    refined = (mass.points["flags"] & REFINED) > 0
    np.testing.assert_array_equal(mass.coordinates(ids["HRG"])[0], plain.coordinates(ids["HRG"])[0])
    for name in ("HRS1", "HRS2"):
        moved = np.hypot(*(np.array(mass.coordinates(ids[name])) - np.array(plain.coordinates(ids[name]))))
        assert np.all((moved[~refined] == 0) | np.isnan(moved[~refined]))  # NaN: two-ray points
        assert moved[refined].max() < 2.0 and np.mean(moved[refined] > 0) > 0.9


def test_two_images_give_group_1(pushbroom_provider, triplet):
    path = make_block(triplet, "two.gpkg", ("HRG", "HRS1"))
    lo, hi = triplet["range"]
    processing.run(
        "pushbroom:matchpoints", {"BLOCK": path, "IMAGES": "HRG, HRS1", "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 8}
    )
    mass = Block(path).points()
    assert len(mass) > 100 and mass.group_counts()[2] == mass.group_counts()[3] == 0
    # a pair has no three-ray point: tie points of group 3 are refused with what to do instead
    with pytest.raises(QgsProcessingException, match=r"no point of group 3 or higher .*Set MIN_GROUP to 1"):
        processing.run("pushbroom:selecttiepoints", {"BLOCK": path, "MIN_GROUP": 3})
    assert "tie_points" not in Block(path).info()
    wide = make_block(triplet, "wide.gpkg", ("HRG", "HRS1"))
    processing.run(
        "pushbroom:matchpoints",
        {"BLOCK": wide, "IMAGES": "HRG, HRS1", "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 8, "WIDE_TEMPLATE": 27},
    )
    assert len(Block(wide).points()) > 1.2 * len(mass)  # the second window reaches weak texture


def test_bad_input_gives_clear_errors(pushbroom_provider, triplet):
    path = make_block(triplet, "bad.gpkg", ("HRG", "HRS1", "HRS2"))
    with pytest.raises(QgsProcessingException, match="not in the block"):
        processing.run("pushbroom:matchpoints", {"BLOCK": path, "IMAGES": "HRG,XS"})
    with pytest.raises(QgsProcessingException, match="matchpoints"):
        processing.run("pushbroom:selecttiepoints", {"BLOCK": path})
    with pytest.raises(QgsProcessingException, match="no tie points.*selecttiepoints"):
        processing.run("pushbroom:matchpoints", {"BLOCK": path, "SEEDS": 1})
    with pytest.raises(QgsProcessingException, match="wide template must be 0 .off. or an odd size larger"):
        processing.run("pushbroom:matchpoints", {"BLOCK": path, "WIDE_TEMPLATE": 20})


def test_cancel_writes_nothing(pushbroom_provider, triplet):
    path = make_block(triplet, "cancel.gpkg", ("HRG", "HRS1", "HRS2"))
    feedback = QgsProcessingFeedback()
    feedback.cancel()
    with pytest.raises(QgsProcessingException, match="cancel"):
        processing.run("pushbroom:matchpoints", {"BLOCK": path, "MIN_HEIGHT": 0, "MAX_HEIGHT": 900}, feedback=feedback)
    assert "mass_points" not in Block(path).info()


class CancelAtProgress(QgsProcessingFeedback):
    """Cancels once the run has reported `percent` progress (a user pressing Cancel while it runs)."""

    def __init__(self, percent):
        super().__init__()
        self.progressChanged.connect(lambda value: self.cancel() if value >= percent else None)


@pytest.mark.slow
def test_a_cancel_in_the_middle_leaves_the_block_as_it_was(pushbroom_provider, triplet):
    path = make_block(triplet, "cancel_later.gpkg", ("HRG", "HRS1", "HRS2"))
    lo, hi = triplet["range"]
    tiles = {"BLOCK": path, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 6, "TILE": 128}
    processing.run("pushbroom:matchpoints", tiles, feedback=QgsProcessingFeedback())
    before = Block(path).info()
    folder = os.path.dirname(path)
    files = sorted(os.listdir(folder))
    feedback = CancelAtProgress(20)
    with pytest.raises(QgsProcessingException, match="cancel"):
        processing.run(
            "pushbroom:matchpoints",
            {**tiles, "EXECUTION": BACKENDS.index("processes"), "WORKERS": 2},
            feedback=feedback,
        )
    after = Block(path).info()
    assert {k: after[k] for k in before} == before  # the same points, counts and generation
    assert sorted(os.listdir(folder)) == files  # no new point folder, no work files
    assert len(Block(path).points()) == int(before["mass_points_count"])


def test_coarse_to_fine_strategy(pushbroom_provider, triplet):
    """STRATEGY 1: the coarse-to-fine matcher (algorithms/matching/coarse_to_fine.py) stores the same
    point format: group 3 (three images) and group 1 (two), provenance in the stats; two images give
    group 1 only; its advanced parameters reach it (a wider grid gives fewer points, smaller tiles
    more tiles, a tile below the minimum a clear error)."""
    lo, hi = triplet["range"]
    path = make_block(triplet, "coarse_to_fine.gpkg", ("HRG", "HRS1", "HRS2"))
    result = processing.run("pushbroom:matchpoints", {"BLOCK": path, "STRATEGY": 1, "MIN_HEIGHT": lo, "MAX_HEIGHT": hi})
    mass = Block(path).points()
    counts = mass.group_counts()
    assert counts[3] > 500 and counts[2] == 0 and counts[3] > counts[1], counts
    assert mass.stats["provenance"] == "coarse_to_fine"
    ids = {r["name"]: r["id"] for r in Block(path).images()}
    assert mass.stats["images"] == [ids["HRG"], ids["HRS1"], ids["HRS2"]]
    assert QgsVectorLayer(result["POINTS"], "mass", "ogr").featureCount() == len(mass)
    path = make_block(triplet, "coarse_to_fine_two.gpkg", ("HRG", "HRS1"))
    two = {"BLOCK": path, "STRATEGY": 1, "IMAGES": "HRG, HRS1", "MIN_HEIGHT": lo, "MAX_HEIGHT": hi}
    processing.run("pushbroom:matchpoints", two)
    default = Block(path).points()
    assert set(default.group_counts().values()) - {0} and default.group_counts()[3] == 0
    assert default.stats.get("tiles", 1) == 1
    processing.run("pushbroom:matchpoints", {**two, "COARSE_TO_FINE_GRID": 20, "COARSE_TO_FINE_TILE": 512})
    coarse = Block(path).points()
    assert len(coarse) < 0.7 * len(default) and coarse.stats["tiles"] == 4, (len(coarse), len(default), coarse.stats)
    with pytest.raises(QgsProcessingException, match="tiles must be at least 512 px"):
        processing.run("pushbroom:matchpoints", {**two, "COARSE_TO_FINE_TILE": 300})


@pytest.mark.slow
def test_every_execution_gives_the_same_points_from_qgis_process(pushbroom_provider, triplet, qgis_process):
    """Region growing's tiles on threads in this process, and on threads, local worker processes and a Dask local
    cluster started by qgis_process (whose sys.executable is not Python): the same points, bit for bit."""
    lo, hi = triplet["range"]
    common = {"IMAGES": "HRG, HRS1", "MIN_HEIGHT": lo, "MAX_HEIGHT": hi, "STEP": 8, "TILE": 256}
    paths = {}
    for execution in ("here", *BACKENDS):
        paths[execution] = make_block(triplet, f"exec_{execution}.gpkg", ("HRG", "HRS1"))
        if execution == "here":
            processing.run("pushbroom:matchpoints", {"BLOCK": paths[execution], **common})
        else:
            chosen = {**common, "EXECUTION": BACKENDS.index(execution), "WORKERS": 2}
            args = [f"--{key}={value}" for key, value in chosen.items()]
            qgis_process("run", "pushbroom:matchpoints", f"--BLOCK={paths[execution]}", *args)
    reference = Block(paths["here"]).points()
    assert len(reference) > 100
    for execution in BACKENDS:
        points = Block(paths[execution]).points()
        assert points.points.tobytes() == reference.points.tobytes(), execution  # NaN included
        assert points.observations.tobytes() == reference.observations.tobytes(), execution


@pytest.fixture(scope="module")
def dense_block(triplet):
    """dense_block(mpgc=False) -> (path, the run's result): the triplet's block matched by the dense strategy
    (every 4th pixel; with DENSE_MPGC or not), once per module, by the first test that asks (with the provider
    registered)."""
    done = {}

    def get(mpgc=False):
        if mpgc not in done:
            path = make_block(triplet, f"dense-{mpgc}.gpkg", ("HRG", "HRS1", "HRS2"))
            lo, hi = triplet["range"]
            done[mpgc] = (
                path,
                processing.run(
                    "pushbroom:matchpoints",
                    {
                        "BLOCK": path,
                        "STRATEGY": 2,
                        "MIN_HEIGHT": lo,
                        "MAX_HEIGHT": hi,
                        "DENSE_TILE": 300,
                        "DENSE_STEP": 4,
                        "DENSE_MPGC": mpgc,
                        "EXECUTION": BACKENDS.index("processes"),
                        "WORKERS": 2,
                    },
                    context=QgsProcessingContext(),
                    feedback=QgsProcessingFeedback(),
                ),
            )
        return done[mpgc]

    return get


@pytest.mark.slow
def test_the_readmes_two_host_cluster_runs_dense_matching(pushbroom_provider, triplet, dense_block, tmp_path):
    """The README's two-host example, its commands as written after its settings (HOST this machine's 127.0.0.1,
    PORT a free port, PUSHBROOM this clone): a scheduler, two workers and the check of the workers; dense matching
    through qgis_process on that cluster gives the points of local processes, bit for bit, and its log names the
    workers and the tiles each ran, with no Python warning and no traceback."""
    readme = readme_commands(REPO / "README.md")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}  # a user's shell
    here = {"PUSHBROOM": str(REPO), "HOST": "127.0.0.1"}

    def shell(command, port):
        return readme_shell(readme, command, {**here, "PORT": str(port)})

    with Cluster(tmp_path, scheduler=lambda port: shell("scheduler", port), env=env) as cluster:
        for _ in range(2):
            cluster.start("worker", shell("worker", cluster.port), env)
        cluster.wait_for_workers(2)
        checked = subprocess.run(shell("check", cluster.port), env=env, capture_output=True, text=True, timeout=120)
        assert (
            checked.returncode == 0
            and checked.stdout.splitlines()[-1] == f"2 of 2 workers run Pushbroom {pushbroom.__version__}"
        ), checked.stdout + checked.stderr
        path = make_block(triplet, "dense-readme-cluster.gpkg", ("HRG", "HRS1", "HRS2"))
        lo, hi = triplet["range"]
        run_env = dict(qgis_process_env(tmp_path / "profile"), PYTHONWARNINGS="ignore:setapi:DeprecationWarning")
        ran = subprocess.run(
            [
                QGIS_PROCESS,
                "run",
                "pushbroom:matchpoints",
                "--",
                f"BLOCK={path}",
                "STRATEGY=2",
                f"MIN_HEIGHT={lo}",
                f"MAX_HEIGHT={hi}",
                "DENSE_TILE=300",
                "DENSE_STEP=4",
                "EXECUTION=2",
                f"DASK_ADDRESS={cluster.address}",
            ],
            env=run_env,
            capture_output=True,
            text=True,
            timeout=600,
        )
    log = ran.stdout + ran.stderr
    assert ran.returncode == 0, log[-3000:]
    reference = Block(dense_block()[0]).points()
    points = Block(path).points()
    assert len(points) > 1000
    assert points.points.tobytes() == reference.points.tobytes()
    assert points.observations.tobytes() == reference.observations.tobytes()
    assert f"the Dask cluster at {cluster.address}: 2 workers (tcp://127.0.0.1:" in log
    rounds = re.findall(r"(.*): (\d+) tasks? on the Dask cluster at ", log)
    tallies = re.findall(r"(.*): tasks per worker: (.*)", log)
    assert len(tallies) == len(rounds) >= 2
    for (what, n), (same, counts) in zip(rounds, tallies):
        # qgis_process writes its progress ("0...10...", "80") before a line
        assert re.sub(r"^[\d.]*", "", what) == re.sub(r"^[\d.]*", "", same)
        assert sum(int(c) for c in re.findall(r"tcp://127\.0\.0\.1:\d+ (\d+)", counts)) == int(n)
    assert not re.search(r"\w+Warning\b|Traceback|semaphore", log), log[-3000:]


@pytest.mark.slow
def test_threads_inside_qgis_process_differ_only_by_the_cblas_it_links(
    pushbroom_provider, triplet, dense_block, tmp_path, figures
):
    """qgis_process links GSL's reference CBLAS before OpenBLAS (docs/architecture.md, "Same bits"): numpy's matrix
    products in its threads sum in another order, and the dense tiles' image coordinates differ from local worker
    processes' (plain Python) by rounding, far below a micro-pixel; with OpenBLAS preloaded, bit for bit."""
    reference = Block(dense_block()[0]).points()  # the tiles in worker processes (/usr/bin/python3)
    lo, hi = triplet["range"]
    env = dict(qgis_process_env(tmp_path / "profile"), PYTHONWARNINGS="ignore:setapi:DeprecationWarning")
    found = {}
    for name, preload in (("as linked", {}), ("OpenBLAS first", {"LD_PRELOAD": openblas()})):
        path = make_block(triplet, f"dense-qgis-process-threads-{len(found)}.gpkg", ("HRG", "HRS1", "HRS2"))
        ran = subprocess.run(
            [
                QGIS_PROCESS,
                "run",
                "pushbroom:matchpoints",
                "--",
                f"BLOCK={path}",
                "STRATEGY=2",
                f"MIN_HEIGHT={lo}",
                f"MAX_HEIGHT={hi}",
                "DENSE_TILE=300",
                "DENSE_STEP=4",
                "EXECUTION=0",
                "WORKERS=2",
            ],
            env={**env, **preload},
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert ran.returncode == 0, (ran.stdout + ran.stderr)[-3000:]
        found[name] = Block(path).points()
    linked = found["as linked"].observations
    assert all(np.array_equal(linked[f], reference.observations[f]) for f in ("point_id", "image_id"))
    worst = max(float(np.nanmax(np.abs(linked[axis] - reference.observations[axis]))) for axis in ("col", "row"))
    figures.report(
        "dense image coordinates, threads inside qgis_process (GSL's CBLAS) against worker processes, "
        "largest difference",
        worst,
        "px",
    )
    assert worst < 1e-9  # rounding: a micro-pixel is 1e-6
    assert found["OpenBLAS first"].observations.tobytes() == reference.observations.tobytes()
    assert found["OpenBLAS first"].points.tobytes() == reference.points.tobytes()


def test_dense_strategy_stores_points_for_the_next_steps(pushbroom_provider, dense_block):
    path, result = dense_block()
    mass = Block(path).points()
    counts = mass.group_counts()
    cols, rows = 600 // 4, 599 // 4
    assert counts[2] > 0.5 * cols * rows and counts[3] == 0  # three rays from two pairs
    assert np.all(mass.points["flags"] & DENSE)
    assert np.isfinite(mass.points["rho_min"]).mean() > 0.35  # LSM refined all its positions (43 %)
    layer = QgsVectorLayer(result["POINTS"], "mass", "ogr")
    assert layer.isValid() and layer.featureCount() == len(mass)


@pytest.mark.parametrize("mpgc", [False, True], ids=["pairwise LSM", "MPGC"])
def test_dense_points_report_a_calibrated_precision(pushbroom_provider, dense_block, triplet, tmp_path, figures, mpgc):
    """The refined dense points' sigma_h in the cloud of pushbroom:intersectpoints (the block's models are the
    truth, so the error is the matching's alone) against their error from the true DSM, on the open classes:
    RMS(dh) / RMS(sigma_h) within 0.8 ... 1.25 (issue 22; dense/precision.py), refined pairwise or by MPGC."""
    path, _ = dense_block(mpgc)
    out = processing.run(
        "pushbroom:intersectpoints",
        {"BLOCK": path, "OUTPUT": str(tmp_path / "dense.las")},
        context=QgsProcessingContext(),
        feedback=QgsProcessingFeedback(),
    )["OUTPUT"]
    las = laspy_module().read(out)
    lon, lat = reproject(np.asarray(las.x), np.asarray(las.y), srs_of("EPSG:32616"), wgs84())
    paths = triplet["paths"]
    dh = np.asarray(las.z) - read_dem(paths["dsm"]).height(lon, lat)
    sigma_h, refined = np.asarray(las["sigma_h"], float), np.isfinite(np.asarray(las["rho"]))
    classes = gdal.Open(str(paths["classes"]))
    gt, values = classes.GetGeoTransform(), classes.ReadAsArray()
    cls = values[
        ((lat - gt[3]) / gt[5]).astype(int).clip(0, values.shape[0] - 1),
        ((lon - gt[0]) / gt[1]).astype(int).clip(0, values.shape[1] - 1),
    ]
    for k in (BARE, CROPS):
        m = refined & (cls == k) & np.isfinite(dh)
        ratio = np.sqrt(np.mean(dh[m] ** 2) / np.mean(sigma_h[m] ** 2))
        figures.report(
            f"dense points' precision ({'MPGC' if mpgc else 'pairwise LSM'}) on {CLASSES[k]}, RMS(dh) / RMS(sigma_h)",
            ratio,
            "",
            f"{m.sum()} refined points, every 4th pixel",
        )
        assert m.sum() > 1500 and 0.8 <= ratio <= 1.25, (k, m.sum(), ratio)


def test_statistical_outlier_removal_of_the_dense_cloud(pushbroom_provider, dense_block, triplet, tmp_path, figures):
    """pushbroom:intersectpoints with OUTLIER_NEIGHBOURS 20 removes the points a single whole-cloud computation
    (outlier_filter on all the points at once, in the same local frame) removes, although it runs part by part;
    and those points are mostly blunders against the true DSM."""
    path, _ = dense_block()
    feedback = QgsProcessingFeedback()
    clouds = [
        processing.run(
            "pushbroom:intersectpoints",
            {"BLOCK": path, "OUTPUT": str(tmp_path / f"k{k}.las"), "OUTLIER_NEIGHBOURS": k, "OUTLIER_FACTOR": 3.0},
            context=QgsProcessingContext(),
            feedback=feedback,
        )["OUTPUT"]
        for k in (0, 20)
    ]
    every, kept = (laspy_module().read(c) for c in clouds)
    lon, lat = reproject(np.asarray(every.x), np.asarray(every.y), srs_of("EPSG:32616"), wgs84())
    x, y = local_metres(lon, lat, (lon.mean(), lat.mean()))
    xyz = np.c_[x, y, np.asarray(every.z)]
    d = mean_distances(xyz, xyz, 20)
    expected = d > threshold(d.size, d.sum(), np.square(d).sum(), 3.0)
    removed = ~np.isin(np.asarray(every["point_id"]), np.asarray(kept["point_id"]))
    assert len(Block(path).point_parts("mass_points")) == 4 and 0.005 < removed.mean() < 0.05
    assert np.count_nonzero(removed != expected) <= 0.01 * expected.sum()  # the LAS's mm rounding at the limit
    dh = np.asarray(every.z) - read_dem(triplet["paths"]["dsm"]).height(lon, lat)
    blunder = np.abs(dh) > 10.0
    figures.report(
        "statistical outlier removal (k 20, n 3) of the dense cloud, removed",
        removed.mean() * 100,
        "%",
        f"{blunder[removed].mean() * 100:.1f} % of them 10 m or more off the true DSM, "
        f"{blunder.mean() * 100:.1f} % of the cloud",
    )
    assert blunder[removed].mean() > 5 * blunder.mean()
