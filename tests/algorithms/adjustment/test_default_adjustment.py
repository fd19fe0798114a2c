"""bundleadjust's defaults on good data (issue 36): the issue's chain (createblock, matchpoints STEP 10,
selecttiepoints CELL 100, importpoints with two check points, bundleadjust with its defaults) converges
for every choice of two check points among the simulator's seven, and the check points land where the
simulator's truth is; an unmeasured control point takes no part; a control point 1 km off is named, or
left out with REMOVE_BLUNDERS; an unconverged solution is not stored.

The scene is conftest's `small_scene` (SceneConfig.small(): 3 km, seed 1, 7 control point candidates),
not the issue's `simulatescene SIZE_KM=3 SEED=1 POINTS=20` (another centre, same size and kind): it is
simulated once per run for other tests already, and main's default adjustment failed on it in the same
way (the issue's chain, check points P003 and P004: "All-NaN slice", then "corrections must be finite",
issue 36). The block is the
session's template at the points' mean height instead of createblock's height search, matched and
thinned once per module; each case copies it.

Accuracy bound (independent of the adjustment's own sigmas): the simulator measures every point with
0.3 px noise; the HRG's 5 m pixels make that 1.5 m per ray on the ground, about 1.4 m per planimetric
component of an intersected check point with the orientation's error from five such control points, so
5 m is 3.5 sigma; the HRS pair's base-to-height ratio 0.83 turns 0.3 px of 5 m rows into a 2.6 m height
sigma (2.4 m with the HRG), so 10 m is 4 sigma."""

import csv
import itertools
import shutil
import warnings

import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import GeometryError, InputError
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowingSettings
from pushbroom.algorithms.steps.adjust_block import AdjustParams, adjust_block
from pushbroom.algorithms.steps.block_matching import MatchParams, match_block_points
from pushbroom.algorithms.steps.block_tie_points import TieParams, select_block_tie_points
from pushbroom.algorithms.steps.point_files import ImportParams, import_points
from tests.helpers.feedback import Feedback

#: the simulator's seven points of SceneConfig.small()
POINTS = [f"P00{k}" for k in range(1, 8)]
#: |dE|, |dN| and |dH| bounds of a check point against the truth (m; module docstring)
PLANIMETRIC_BOUND, HEIGHT_BOUND = 5.0, 10.0


@pytest.fixture(scope="module")
def matched(small_scene_block, tmp_path_factory):
    """The folder of a block of the small scene after matchpoints STEP 10 and selecttiepoints CELL 100."""
    template, rows = small_scene_block
    assert [r["id"] for r in rows] == POINTS
    folder = tmp_path_factory.mktemp("default_adjustment")
    shutil.copy(template, folder / "block.gpkg")
    settings = RegionGrowingSettings(grow=GrowParams(step=10))
    match_block_points(str(folder / "block.gpkg"), MatchParams(settings=settings))
    select_block_tie_points(str(folder / "block.gpkg"), TieParams(cell=100.0))
    return folder


def block_with_points(matched, small_scene, tmp_path, check, edit=None, keep_implausible=False):
    """A copy of the matched block with the simulator's points imported (`check` the check points); `edit`
    changes the CSV's rows ({id: row}) first. Returns the block path."""
    folder = tmp_path / "block"
    shutil.copytree(matched, folder)
    with open(small_scene["points"], newline="") as f:
        rows = list(csv.DictReader(f))
    if edit:
        edit({r["id"]: r for r in rows})
    with open(tmp_path / "points.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, rows[0].keys())
        writer.writeheader()
        writer.writerows(rows)
    import_points(
        str(folder / "block.gpkg"),
        str(tmp_path / "points.csv"),
        ImportParams(check_ids=",".join(check), suffix="_meas", keep_implausible=keep_implausible),
    )
    return str(folder / "block.gpkg")


def adjusted(path, feedback, **settings):
    """adjust_block with the defaults (and `settings`), any Python warning an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return adjust_block(path, AdjustParams(**settings), feedback)


def assert_check_points_near_the_truth(path, check):
    ground = Block(path).residuals()[1]
    for name in check:
        d_e, d_n, d_h, _ = ground[name]
        assert abs(d_e) < PLANIMETRIC_BOUND and abs(d_n) < PLANIMETRIC_BOUND, (name, d_e, d_n)
        assert abs(d_h) < HEIGHT_BOUND, (name, d_h)


@pytest.mark.parametrize("check", list(itertools.combinations(POINTS, 2)), ids="-".join)
def test_the_defaults_converge_and_check_points_meet_the_truth(matched, small_scene, tmp_path, check, figures):
    path = block_with_points(matched, small_scene, tmp_path, check)
    log = Feedback()
    result = adjusted(path, log)
    assert any(", converged" in m for m in log.messages) and 0.5 < result.sigma0 < 2.0
    ground = Block(path).residuals()[1]
    figures.report(
        f"default adjustment, check points {'+'.join(check)}: dE, dN, dH (m)",
        [tuple(round(v, 2) for v in ground[n][:3]) for n in check],
    )
    assert_check_points_near_the_truth(path, check)


def test_an_unmeasured_control_point_takes_no_part(matched, small_scene, tmp_path):
    """P001 imported without measurements: a note names it, the other four control the block."""

    def blank(rows):
        for key in rows["P001"]:
            if key.endswith("_meas"):
                rows["P001"][key] = ""

    path = block_with_points(matched, small_scene, tmp_path, ("P002", "P006"), blank)
    log = Feedback()
    adjusted(path, log)
    assert any("take no part: P001" in m for m in log.messages)
    assert_check_points_near_the_truth(path, ("P002", "P006"))


def test_a_control_point_1_km_off_is_named_or_left_out(matched, small_scene, tmp_path):
    """P003 moved 1 km north: importpoints refuses it, naming it; imported anyway (KEEP_IMPLAUSIBLE), the
    adjustment by default raises an InputError naming it with its offset and stores nothing; with
    REMOVE_BLUNDERS it is left out with a warning and a report section, and the four others control the
    block."""

    def move(rows):
        rows["P003"]["lat"] = str(float(rows["P003"]["lat"]) + 1000.0 / 111_000.0)

    with pytest.raises(InputError, match=r"P003: its measurements meet .* and (99\d|10\d\d) m beside its position"):
        block_with_points(matched, small_scene, tmp_path / "refused", ("P002", "P006"), move)
    path = block_with_points(matched, small_scene, tmp_path, ("P002", "P006"), move, keep_implausible=True)
    before = Block(path).generations()
    named = r"P003: HRG [\d.]+ px \((99\d|100\d) m\).*ground coordinates.*REMOVE_BLUNDERS"  # 1 km within 1 %
    with pytest.raises(InputError, match=named):
        adjusted(path, Feedback())
    assert Block(path).generations() == before
    log = Feedback()
    result = adjusted(path, log, remove_blunders=True, report=str(tmp_path / "r.html"))
    assert any(m.startswith("left out before the adjustment, grossly off: P003") for m in log.messages)
    assert "<td>P003</td><td>HRS1</td>" in open(result.report).read()  # the screening's section
    assert_check_points_near_the_truth(path, ("P002", "P006"))


def test_a_measurement_30_px_off_is_left_to_data_snooping(matched, small_scene, tmp_path):
    """P004's HRS2 column 30 px off: the screen notes it, the adjustment runs, and data snooping flags that
    measurement (its stored normalised residual above the critical value 3.29)."""

    def slip(rows):
        rows["P004"]["HRS2_col_meas"] = str(float(rows["P004"]["HRS2_col_meas"]) + 30.0)

    path = block_with_points(matched, small_scene, tmp_path, ("P002", "P006"), slip)
    log = Feedback()
    adjusted(path, log)
    assert any(m.startswith("far off, left to data snooping: P004: HRS2") for m in log.messages)
    image = Block(path).residuals()[0]
    hrs2 = next(r["id"] for r in Block(path).images() if r["name"] == "HRS2")
    assert max(abs(w) for w in image["P004", hrs2][2:]) > 3.29


def test_an_unconverged_solution_is_not_stored(matched, small_scene, tmp_path):
    """MAX_ITERATIONS 1: a GeometryError saying so, the block's models and residuals as they were, and the
    report opens with the alert."""
    path = block_with_points(matched, small_scene, tmp_path, ("P002", "P006"))
    before = Block(path).generations()
    said = r"did not converge in 1 iteration\(s\).*nothing was stored.*MAX_ITERATIONS"
    with pytest.raises(GeometryError, match=said):
        adjusted(path, Feedback(), max_iterations=1, report=str(tmp_path / "r.html"))
    assert Block(path).generations() == before and Block(path).residuals() == ({}, {})
    text = open(tmp_path / "r.html").read()
    assert "<h2 class='alert'>Not converged: these results were not stored</h2>" in text
    assert text.index("Not converged") < text.index("<h2>Adjustment</h2>")
