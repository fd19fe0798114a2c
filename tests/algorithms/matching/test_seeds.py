"""Seeds (algorithms/matching/seeds.py) and windowed imagery (imagery.py)."""

import numpy as np
import pytest

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.height_range import HeightRange
from pushbroom.algorithms.matching.imagery import Image
from pushbroom.algorithms.matching.interest import interest_points
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.seeds import automatic_seeds, seeds_from_points


def test_image_window_clipping_and_nodata(tmp_path):
    from osgeo import gdal

    data = np.arange(20 * 30, dtype=np.uint16).reshape(20, 30)
    data[5, 7] = 9999
    path = str(tmp_path / "img.tif")
    ds = gdal.GetDriverByName("GTiff").Create(path, 30, 20, 1, gdal.GDT_UInt16)
    ds.GetRasterBand(1).WriteArray(data)
    ds.GetRasterBand(1).SetNoDataValue(9999)
    ds = None
    image = Image(path)
    assert image.size == (30, 20)
    win, x0, y0 = image.read(-3, 2, 12, 40)
    assert (x0, y0) == (0, 2) and win.shape == (18, 9) and win.dtype == np.float32
    assert np.isnan(win[3, 7]) and win[0, 0] == data[2, 0]
    empty, _, _ = image.read(100, 100, 5, 5)
    assert empty.size == 0
    with pytest.raises(InputError):
        Image(str(tmp_path / "missing.tif"))


def test_interest_points_on_texture_not_on_flat():
    rng = np.random.default_rng(0)
    from scipy.ndimage import gaussian_filter

    img = gaussian_filter(rng.standard_normal((100, 100)), 1.5).astype(np.float32)
    img[:, 50:] = 0.0
    img[40:45, 10:15] = np.nan  # nodata: no point within reach of it
    x, y, w = interest_points(img, patch=25, window=5, border=6)
    assert len(x) > 3 and np.all(x < 52)  # texture and its edge only
    assert np.all((x > 6) & (y > 6) & (x < 94) & (y < 94)) and np.all(np.diff(w) <= 0)
    assert not np.any((x > 7) & (x < 18) & (y > 37) & (y < 48))


def test_height_range():
    assert HeightRange.resolve(300.0, None).bounds == (-200.0, 800.0)
    assert HeightRange.resolve((1, 2)).bounds == (1.0, 2.0)
    with pytest.raises(InputError):
        HeightRange.resolve(None, object())
    with pytest.raises(InputError):
        HeightRange.resolve((5, 1))


@pytest.fixture(scope="module")
def scene(small_matching_scene):
    return small_matching_scene


@pytest.mark.slow
@pytest.mark.ratchet
def test_automatic_seeds_are_correct(scene, figures):
    seeds = automatic_seeds(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), GrowParams(), scene.height_range
    )
    x2, y2, _ = scene.truth(seeds["x1"], seeds["y1"])
    error = np.hypot(seeds["x2"] - x2, seeds["y2"] - y2)
    figures.report("automatic seeds", len(seeds))
    figures.report("median error", np.median(error), "px")
    figures.report("max error", error.max(), "px")
    assert len(seeds) > 20
    assert np.mean(error > 1.0) < 0.1 and np.median(error) < 0.4


def test_a_sliver_box_has_no_seed(scene):
    cols, rows = scene.model1.size
    for box in ((cols - 4, 0, cols, rows), (0, rows - 6, cols, rows)):  # the last tile of a 1028 px image ...
        assert (
            len(
                automatic_seeds(
                    ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
                    GrowParams(),
                    scene.height_range,
                    box=box,
                )
            )
            == 0
        )
    assert (
        len(
            automatic_seeds(
                ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
                GrowParams(),
                scene.height_range,
                box=(0, 0, 200, 200),
            )
        )
        > 0
    )


@pytest.mark.slow
def test_seeds_from_points_with_and_without_approximations(scene):
    x1 = np.array([150.5, 300.5, 450.5, 200.5])
    y1 = np.array([150.5, 300.5, 450.5, 420.5])
    recs, ok = seeds_from_points(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2), x1, y1, GrowParams(), scene.height_range
    )
    x2, y2, _ = scene.truth(x1, y1)
    assert ok.sum() >= 1
    assert np.all(np.hypot(recs["x2"][ok] - x2[ok], recs["y2"][ok] - y2[ok]) < 1.0)
    recs2, ok2 = seeds_from_points(
        ImagePair(scene.image1, scene.image2, scene.model1, scene.model2),
        x1,
        y1,
        GrowParams(),
        scene.height_range,
        x2=x2 + 1.5,
        y2=y2 - 1.0,
    )
    assert ok2.sum() >= 1
    assert np.all(np.hypot(recs2["x2"][ok2] - x2[ok2], recs2["y2"][ok2] - y2[ok2]) < 1.0)
