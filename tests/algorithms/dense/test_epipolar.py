"""Epipolar grids against the sensor models they come from: conjugate points on one row over the height
range (real Pleiades RPCs, simulated SPOT 5 HRG/HRS), the disparity's sign and range, the epipolar
pixel's ground size against PROJ, and the pairs that have no epipolar geometry."""

import dataclasses

import numpy as np
import pytest
from osgeo import osr

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense.epipolar import disparity_range, epipolar_grid
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.pair_geometry import predict

ROW_TOLERANCE = 0.05  # epipolar px: issue 22's bound
ANGLE = 0.01  # rad: the largest angle between a tile's epipolar lines and their mean direction


def spot_pair(small_scene, first, second):
    models = [sensors.load(small_scene["images"][n]["metadata"]) for n in (first, second)]
    lo, hi = read_dem(small_scene["dsm"]).height_range
    return models, (lo - 300.0, hi + 300.0)


def pair_cases(request):
    """(model1, model2, box1, height range) of the parametrised case."""
    case = request.param
    if case == "pleiades":
        triplet = request.getfixturevalue("pleiades_triplet")
        return sensors.load(triplet[1]), sensors.load(triplet[0]), (200, 300, 712, 812), (1800.0, 2800.0)
    if case == "ventoux":
        pair = request.getfixturevalue("ventoux_pair")
        m1, m2 = (sensors.load(p) for p in pair)
        return m1, m2, (0, 0, 500, 500), m1.height_range
    models, hr = spot_pair(request.getfixturevalue("small_scene"), *case.split("-"))
    return models[0], models[1], (50, 60, 550, 560), hr


@pytest.fixture(params=["pleiades", "ventoux", "HRG-HRS1", "HRS1-HRS2"])
def case(request):
    return pair_cases(request)


def test_conjugate_points_lie_on_one_row_over_the_height_range(case, figures):
    model1, model2, box, hr = case
    grid = epipolar_grid(model1, model2, box, hr)
    rng = np.random.default_rng(0)
    x1 = rng.uniform(box[0], box[2], 300)
    y1 = rng.uniform(box[1], box[3], 300)
    u1, v1 = grid.epipolar1(x1, y1)
    assert np.isfinite(u1).all()
    heights = np.linspace(hr[0], hr[1], 21)
    d, dv = [], []
    for h in heights:
        u2, v2 = grid.epipolar2(*predict(model1, model2, x1, y1, np.full(x1.size, h)))
        d.append(u2 - u1)
        dv.append(np.abs(v2 - v1))
    d, dv = np.array(d), np.array(dv)
    figures.report(
        f"epipolar row error, {type(model1).__name__} tile {box} over {hr[1] - hr[0]:.0f} m, max",
        dv.max(),
        "px",
        f"stated {grid.row_error:.4f} px; disparity {d.min():.1f} .. {d.max():.1f} px",
    )
    assert dv.max() < ROW_TOLERANCE and grid.row_error < ROW_TOLERANCE
    assert (np.diff(d, axis=0) > 0).all()  # the disparity grows with the height
    d_lo, d_hi = disparity_range(model1, model2, grid, hr)
    assert d_lo - 0.5 <= d.min() and d.max() <= d_hi + 0.5
    # the grid's positions are the model's: image 2 at the middle height, to the stated error
    x2, y2 = grid.image2(u1, v1)
    e2 = np.hypot(*(np.array([x2, y2]) - np.array(predict(model1, model2, x1, y1, np.full(x1.size, grid.heights[1])))))
    assert e2.max() <= grid.interpolation_error + 1e-3 < 0.01
    # along(): a move along the epipolar curve (one point's image 2 at two heights) keeps its length, one across has
    # none (the tile's epipolar lines are parallel to within ANGLE rad)
    xa, ya = predict(model1, model2, x1, y1, np.full(x1.size, grid.heights[1]))
    xb, yb = predict(model1, model2, x1, y1, np.full(x1.size, grid.heights[1] + 0.05 * (hr[1] - hr[0])))
    dx, dy = xb - xa, yb - ya
    length = np.hypot(dx, dy)
    assert (1.0 - np.abs(grid.along(dx, dy)) / length).max() < 0.5 * ANGLE**2
    assert (np.abs(grid.along(-dy, dx)) / length).max() < ANGLE
    # nodes outside a model's domain are NaN: along() fits the others
    holed = dataclasses.replace(grid, q=grid.q.copy())
    holed.q[0, :] = np.nan
    assert np.allclose(holed.along(dx, dy), grid.along(dx, dy), rtol=0.5 * ANGLE**2)


def ecef(lon, lat, h):
    s = osr.SpatialReference()
    s.ImportFromEPSG(4979)
    t = osr.SpatialReference()
    t.ImportFromEPSG(4978)
    for r in (s, t):
        r.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    return np.array(osr.CoordinateTransformation(s, t).TransformPoints(np.column_stack([lon, lat, h])))


def pixel_area(model, x, y, h):
    """Ground area (m^2) of the pixel centred at (x, y) at height h, from its corners through PROJ."""
    xs, ys = np.array([x - 0.5, x + 0.5, x + 0.5, x - 0.5]), np.array([y - 0.5, y - 0.5, y + 0.5, y + 0.5])
    p = ecef(*model.image_to_ground(xs, ys, np.full(4, h)), np.full(4, h))
    return 0.5 * (
        np.linalg.norm(np.cross(p[1] - p[0], p[3] - p[0])) + np.linalg.norm(np.cross(p[1] - p[2], p[3] - p[2]))
    )


@pytest.mark.parametrize("first, second", [("HRG", "HRS1"), ("HRS1", "HRG")])
def test_the_epipolar_pixel_is_the_coarser_image_s_ground_sample(small_scene, first, second):
    (m1, m2), hr = spot_pair(small_scene, first, second)
    grid = epipolar_grid(m1, m2, (200, 200, 400, 400), hr)
    h = grid.heights[1]
    x1, y1 = grid.image1(np.array([0.0, 1.0, 0.0]) + 10, np.array([0.0, 0.0, 1.0]) + 10)
    p = ecef(*m1.image_to_ground(x1, y1, np.full(3, h)), np.full(3, h))
    assert np.linalg.norm(p[1] - p[0]) == pytest.approx(grid.gsd, rel=0.01)
    assert np.linalg.norm(p[2] - p[0]) == pytest.approx(grid.gsd, rel=0.01)
    x2, y2 = predict(m1, m2, x1[:1], y1[:1], np.full(1, h))
    a1, a2 = pixel_area(m1, x1[0], y1[0], h), pixel_area(m2, x2[0], y2[0], h)
    # HRS: 10 m x 5 m, HRG 5 m (both slanted): the HRS pixel sets the epipolar pixel
    assert grid.gsd == pytest.approx(np.sqrt(max(a1, a2)), rel=0.01)
    assert grid.gsd > 1.3 * np.sqrt(min(a1, a2))


class Elsewhere:
    """A model whose every ground point lies outside its image (NaN): a pair that does not overlap."""

    size = (100, 100)

    def ground_to_image(self, lon, lat, h):
        return np.full(np.shape(lon), np.nan), np.full(np.shape(lon), np.nan)

    def image_to_ground(self, col, row, h):
        return np.full(np.shape(col), np.nan), np.full(np.shape(col), np.nan)


def test_a_pair_without_epipolar_geometry_is_a_clear_error(small_scene):
    (m1, _), hr = spot_pair(small_scene, "HRG", "HRS1")
    with pytest.raises(InputError, match="parallel"):
        epipolar_grid(m1, m1, (0, 0, 200, 200), hr)  # one image twice: no stereo base
    with pytest.raises(InputError, match="do not overlap"):
        epipolar_grid(m1, Elsewhere(), (0, 0, 200, 200), hr)
