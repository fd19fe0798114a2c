"""The terrain height range found by matching (algorithms/matching/height_search.py) and the block made
without a DEM and without a height (steps/block_creation.py)."""

import numpy as np
import pytest

from pushbroom.algorithms import sensors
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching import height_search as hs
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.steps.block_creation import CreateParams, create_block
from pushbroom.algorithms.surface.intersection import Measurements, intersect
from tests.helpers.feedback import Feedback

NAMES = ("HRG", "HRS1", "HRS2")


def test_robust_range_drops_mismatches_and_widens_by_the_margin():
    rng = np.random.default_rng(3)
    terrain = rng.uniform(200.0, 600.0, 500)
    blunders = np.array([2000.0, 4000.0, 8000.0])
    lo, hi, median, kept, rejected = hs.robust_range(np.concatenate([terrain, blunders, [np.nan]]), (-550, 8900))
    assert rejected == 3 and kept == 500
    p_lo, p_hi = np.percentile(terrain, hs.PERCENTILES)
    margin = hs.MARGIN * (p_hi - p_lo)
    assert lo == pytest.approx(p_lo - margin) and hi == pytest.approx(p_hi + margin)
    assert median == pytest.approx(np.median(terrain))
    # flat terrain: the margin is at least MIN_MARGIN; the validity range clips it
    lo, hi, *_ = hs.robust_range(np.full(50, 100.0), (80.0, 1000.0))
    assert (lo, hi) == (80.0, 100.0 + hs.MIN_MARGIN)
    assert hs.robust_range(terrain[: hs.MIN_POINTS - 1], (-550, 8900)) is None


def test_windows_cover_a_small_image_and_spread_over_a_large_one():
    boxes = hs.windows((1028, 1040))
    area = sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in boxes)
    assert area == 1028 * 1040 and all(min(x1 - x0, y1 - y0) > 300 for x0, y0, x1, y1 in boxes)
    boxes = hs.windows((24000, 12000))
    assert len(boxes) == hs.WINDOWS**2 and all(x1 - x0 == hs.WINDOW == y1 - y0 for x0, y0, x1, y1 in boxes)
    assert boxes[0][:2] == (0, 0) and boxes[-1][2:] == (24000, 12000)


def test_validity_range_of_rpcs_and_of_spot(pleiades_triplet, small_scene):
    rpcs = [sensors.load(p) for p in pleiades_triplet]
    assert hs.validity_range(rpcs) == (40.0, 1090.0)  # HEIGHT_OFF 565 +- HEIGHT_SCALE 525 in the RPC00B tags
    spot = sensors.load(small_scene["images"]["HRG"]["metadata"])
    assert hs.validity_range([spot, rpcs[0]]) == (40.0, 1090.0)
    assert hs.validity_range([spot]) == hs.EARTH_HEIGHTS


def test_a_spot_block_without_height_finds_the_terrain(small_scene, small_scene_matched, figures, tmp_path):
    # the terrain as each pair's supplied models see it (about 30 m off, so their heights are up to some 100 m
    # off the true DSM's): region growing's points over the DSM's range, intersected pair by pair
    points = small_scene_matched(GrowParams())
    models = {k: sensors.load(small_scene["images"][n]["metadata"]) for k, n in enumerate(NAMES, start=1)}
    heights = []
    for other in (2, 3):
        obs = points.observations[np.isin(points.observations["image_id"], (1, other))]
        result = intersect(models, Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]))
        heights.append(result.h[result.ok & (result.rays == 2)])
    heights = np.concatenate(heights)
    log = Feedback()
    create_block(str(tmp_path / "b.gpkg"), [small_scene["images"][n]["imagery"] for n in NAMES], CreateParams(), log)
    blk = Block(str(tmp_path / "b.gpkg"))
    h_min, h_max = blk.height_range()
    inside = ((heights >= h_min) & (heights <= h_max)).mean()
    figures.report(
        "simulated 3 km triplet, no height: range found; region growing's pair heights (min, max)",
        [h_min, h_max, heights.min(), heights.max()],
        "m",
    )
    figures.report("simulated 3 km triplet, no height: region growing's pair heights inside the range", inside)
    assert inside > 0.99 and h_max - h_min < 3.0 * np.ptp(heights), (h_min, h_max, heights.min(), heights.max())
    assert "points matched over -550 to 8900 m" in blk.info()["height_search"]
    assert any("terrain heights" in m for m in log.messages)


def test_textureless_images_ask_for_a_height(small_scene, tmp_path):
    from osgeo import gdal

    paths = []
    for n in NAMES[:2]:
        src = gdal.Open(small_scene["images"][n]["imagery"])
        path = str(tmp_path / f"{n}.tif")
        ds = gdal.GetDriverByName("GTiff").Create(path, src.RasterXSize, src.RasterYSize, 1, gdal.GDT_UInt16)
        ds.GetRasterBand(1).Fill(500)
        ds = None
        paths.append(path)
    models = [sensors.load(small_scene["images"][n]["metadata"]) for n in NAMES[:2]]
    with pytest.raises(InputError, match="terrain height could not be found: 0 point.*give a DEM or a mean height"):
        hs.search_heights(paths, models)
    with pytest.raises(InputError, match="from one image"):
        hs.search_heights(paths[:1], models[:1])


def test_a_single_image_block_without_height_is_made_at_its_rpc_mean_height(pleiades_triplet, tmp_path):
    log = Feedback()
    create_block(str(tmp_path / "b.gpkg"), [str(pleiades_triplet[0])], CreateParams(), log)
    assert Block(str(tmp_path / "b.gpkg")).height_range() == (565.0 - 500.0, 565.0 + 500.0)
    assert any("no DEM and no height given" in m for m in log.messages)


def test_an_existing_block_is_refused_before_the_search(small_scene, tmp_path, monkeypatch):
    """No minutes of matching before the refusal: the output is checked first."""
    (tmp_path / "b.gpkg").write_bytes(b"a block")

    def searched(*args, **kwargs):
        raise AssertionError("the height search ran")

    monkeypatch.setattr("pushbroom.algorithms.steps.block_creation.search_heights", searched)
    with pytest.raises(InputError, match="exists already"):
        create_block(str(tmp_path / "b.gpkg"), [small_scene["images"][n]["imagery"] for n in NAMES], CreateParams())
    assert (tmp_path / "b.gpkg").read_bytes() == b"a block"
