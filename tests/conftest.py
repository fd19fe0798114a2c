"""Shared fixtures: the real test data in SHARED_DATA (skipped with a reason where absent), the
simulated scenes (each configuration simulated once per run), the small SPOT 5 triplet most
engine and plugin tests use and its marked variant of the measurement tests, and `figures`, through
which tests report what they measured."""

import fcntl
import hashlib
import os
import pathlib
import pickle
import sys

import pytest

from pushbroom.algorithms.dem_store import read_dem
from tests.helpers.figures import Figures

REPO = pathlib.Path(__file__).resolve().parents[1]
SHARED_DATA = pathlib.Path(os.environ.get("PUSHBROOM_SHARED_DATA", REPO.parent / "shared" / "data"))
#: where a run's figures are written (and shown in the terminal summary)
FIGURES_PATH = REPO / "build" / "test-figures.md"
_FIGURES = pytest.StashKey[Figures]()


def shared_file(*parts):
    """Path of a file in SHARED_DATA, or skip the test with the reason it is missing."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(
            f"real test data not available: {path} (set PUSHBROOM_SHARED_DATA or put the data in {SHARED_DATA})"
        )
    return path


@pytest.fixture
def spot5_dim():
    return shared_file("spot5_hrg1_2005", "METADATA.DIM")


@pytest.fixture
def spot2_dim():
    return shared_file("spot2_hrv1_1999", "METADATA.DIM")


@pytest.fixture(params=["img_01.tif", "img_02.tif", "img_03.tif"])
def triplet_image(request):
    return shared_file("pleiades_triplet", request.param)


@pytest.fixture(scope="session")
def pleiades_triplet():
    """The three Pleiades triplet crops img_01, img_02, img_03 (paths, in file order)."""
    return [shared_file("pleiades_triplet", f"img_0{k}.tif") for k in (1, 2, 3)]


@pytest.fixture(params=["left_image", "right_image"])
def ventoux_image(request):
    return shared_file("pleiades_pair_ventoux", request.param + ".tif")


@pytest.fixture(scope="session")
def ventoux_pair():
    """The Ventoux pair's left_image and right_image (paths)."""
    return [shared_file("pleiades_pair_ventoux", f"{side}_image.tif") for side in ("left", "right")]


@pytest.fixture(scope="session")
def simulated(tmp_path_factory):
    """simulated(config) -> simulate_scene's paths of a SceneConfig: each distinct resolved
    configuration is simulated once per run, into a folder of the run that the xdist workers share (the first
    worker to ask simulates it, under a lock; the others wait and read its paths), and shared read-only
    (tests write their blocks and outputs into their own folders). Tests of simulate_scene itself
    call it directly."""
    from pushbroom.algorithms.simulation import simulate_scene

    base = tmp_path_factory.getbasetemp()
    shared = (base.parent if "PYTEST_XDIST_WORKER" in os.environ else base) / "scenes"
    shared.mkdir(exist_ok=True)
    done = {}

    def get(config):
        key = repr(config.resolved())
        if key not in done:
            folder = shared / hashlib.sha1(key.encode()).hexdigest()[:16]
            record = folder / "paths.pickle"
            with open(f"{folder}.lock", "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)
                if not record.exists():
                    paths = simulate_scene(config, folder / "scene")
                    record.write_bytes(pickle.dumps(paths))
                done[key] = pickle.loads(record.read_bytes())
        return done[key]

    return get


@pytest.fixture(scope="session")
def small_scene(simulated):
    """simulate_scene paths of the default 3 km SPOT 5 triplet (SceneConfig.small())."""
    from pushbroom.algorithms.simulation import SceneConfig

    return simulated(SceneConfig.small())


@pytest.fixture(scope="session")
def small_matching_scene(small_scene):
    """matching_scene.Scene of the small scene (HRG -> HRS1: models, truth models, DSM, classes, ground
    texture), built once per run and shared read-only."""
    from tests.helpers.matching_scene import Scene

    return Scene(small_scene)


@pytest.fixture(scope="session")
def small_scene_matched(small_scene):
    """small_scene_matched(params, refine=True) -> MultiPoints of match_block on the small scene's
    HRG, HRS1, HRS2 (supplied models, the DSM's height range +- 100 m, 4 workers): each (GrowParams,
    refine) matched once per run and shared read-only."""
    from pushbroom.algorithms import sensors
    from pushbroom.algorithms.matching.region_growing_strategy import match_block

    names = ("HRG", "HRS1", "HRS2")
    lo, hi = read_dem(small_scene["dsm"]).height_range
    done = {}

    def get(params, refine=True):
        key = (repr(params), refine)
        if key not in done:
            done[key] = match_block(
                [small_scene["images"][n]["imagery"] for n in names],
                [sensors.load(small_scene["images"][n]["metadata"]) for n in names],
                params=params,
                height_range=(lo - 100.0, hi + 100.0),
                workers=4,
                mpgc=refine,
            )
        return done[key]

    return get


@pytest.fixture(scope="session")
def small_scene_block(small_scene, tmp_path_factory):
    """A template block (copy it before changing it) of the small scene's HRG, HRS1, HRS2 at the mean
    height of its point candidates, with the candidates' points.csv rows: (block path, rows)."""
    import csv

    import numpy as np

    from pushbroom.algorithms.block import Block

    with open(small_scene["points"], newline="") as f:
        rows = list(csv.DictReader(f))
    path = tmp_path_factory.mktemp("small_scene_block") / "template.gpkg"
    images = Block.open_images([small_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    Block.create(path, images, height=float(np.mean([float(r["h"]) for r in rows])))
    return path, rows


@pytest.fixture(scope="session")
def marked_scene(simulated):
    """simulate_scene paths of SceneConfig.small(markers=True): the small triplet with markers painted
    at its points (signalised control points; the unmarked scene's points lie in uniform fields where
    matching has nothing to hold on to), shared read-only."""
    from pushbroom.algorithms.simulation import SceneConfig

    return simulated(SceneConfig.small(markers=True))


@pytest.fixture(scope="session")
def marked_block(marked_scene, tmp_path_factory):
    """A template block (copy it before changing it) of the marked scene's HRG, HRS1, HRS2 at the
    mean height of its points."""
    import csv

    import numpy as np

    from pushbroom.algorithms.block import Block

    with open(marked_scene["points"], newline="") as f:
        height = float(np.mean([float(r["h"]) for r in csv.DictReader(f)]))
    path = tmp_path_factory.mktemp("marked_block") / "template.gpkg"
    images = Block.open_images([marked_scene["images"][n]["imagery"] for n in ("HRG", "HRS1", "HRS2")])
    Block.create(path, images, height=height)
    return path


@pytest.fixture
def block_path(marked_block, tmp_path):
    """A copy of the marked block this test may change: its path."""
    import shutil

    path = tmp_path / "block.gpkg"
    shutil.copy(marked_block, path)
    return str(path)


@pytest.fixture(scope="session")
def marked_points(marked_scene):
    """The marked scene's points: {id: row} (true lon/lat/h, true image positions <image>_col/_row and
    the simulated measurements <image>_col_meas/_row_meas)."""
    import csv

    with open(marked_scene["points"], newline="") as f:
        return {r["id"]: {k: (v if k == "id" else float(v)) for k, v in r.items()} for r in csv.DictReader(f)}


@pytest.fixture(scope="session")
def figures(request):
    """figures.report(name, value, unit="", note="") and figures.table(name, rows): what the running test
    (or a fixture it set up) measured, shown in the terminal summary and written to build/test-figures.md."""
    return request.config.stash[_FIGURES]


def pytest_configure(config):
    config.stash[_FIGURES] = Figures()


def in_xdist_worker(config):
    """Whether this session is a pytest-xdist worker (`make test` runs the suite on two)."""
    return hasattr(config, "workerinput")


def xdist_group(nodeid):
    """The pytest-xdist group of a test: its file, so that a module fixture is built once; the real-data tests
    all in one, as their session fixtures (tests/real/conftest.py) are minutes of matching shared between files."""
    path = nodeid.split("::")[0]
    return "real data" if path.startswith("tests/real/") else path


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's worker reads the groups into the node ids
def pytest_collection_modifyitems(config, items):
    """In a pytest-xdist worker (`make test`: two, --dist loadgroup, which hands out the largest groups first),
    each test in its xdist_group."""
    if in_xdist_worker(config):
        for item in items:
            item.add_marker(pytest.mark.xdist_group(xdist_group(item.nodeid)))


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    # a worker's node ids end in "@<group>" (pytest-xdist): the figures are the test's
    nodeid = item.nodeid
    if in_xdist_worker(item.config):
        nodeid = nodeid.removesuffix(f"@{xdist_group(nodeid)}")
    item.config.stash[_FIGURES].current = nodeid


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    figures = config.stash[_FIGURES]
    if figures:
        terminalreporter.write_sep("=", f"figures measured by the tests (also in {FIGURES_PATH})")
        for line in figures.lines():
            terminalreporter.write_line(line)


_EXIT = {"status": 0}


@pytest.fixture
def pushbroom_provider(qgis_processing, qgis_iface):
    """Processing initialised and the plugin's provider registered (removed afterwards)."""
    from qgis.core import QgsApplication

    import pushbroom

    plugin = pushbroom.classFactory(qgis_iface)
    plugin.initProcessing()
    yield QgsApplication.processingRegistry().providerById("pushbroom")
    plugin.unload()


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    """A pytest-xdist worker's figures, into the session's."""
    node.config.stash[_FIGURES].merge(getattr(node, "workeroutput", {}).get("figures", {}))  # none if it crashed


def pytest_sessionfinish(session, exitstatus):
    _EXIT["status"] = int(exitstatus)
    figures = session.config.stash[_FIGURES]
    if in_xdist_worker(session.config):
        session.config.workeroutput["figures"] = figures.entries()
        return
    if figures:
        from pushbroom.algorithms.atomic import write_text

        FIGURES_PATH.parent.mkdir(exist_ok=True)
        write_text(FIGURES_PATH, figures.markdown(), what="the tests' figures")


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """Leave with pytest's exit status once everything (summary, plugins' clean-up) is done.

    QGIS 3.22 can segfault while the interpreter tears down its objects after
    QgsApplication.exitQgis() (seen after a Processing run that failed in processAlgorithm),
    which would turn a passing run into a crash. Nothing of ours runs after this point. A pytest-xdist worker
    leaves as pytest-xdist has it (its results are sent, the controller gives the exit status)."""
    if in_xdist_worker(config):
        return
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(_EXIT["status"])
