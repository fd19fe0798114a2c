"""Every SPOT kernel against a plain numpy reference on small synthetic data."""

import numpy as np
import pytest
from osgeo import osr
from scipy.optimize import brentq

from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.errors import GeometryError, InputError
from pushbroom.algorithms.geodesy import ecef_to_geodetic, geodetic_to_ecef
from pushbroom.algorithms.sensors import spot_frames as frames, spot_kernels as k
from pushbroom.algorithms.sensors.base import SensorModel
from pushbroom.algorithms.sensors.spot import SpotModel, integrated_attitude, lagrange_window
from pushbroom.algorithms.sensors.spot_orientation import Corrections
from tests.helpers.spot_synthetic import synthetic_orientation

RNG = np.random.default_rng(7)
#: unit-size entries of up to four 3 x 3 rotation products whose sines and cosines numpy's SIMD code gives
#: to 4 ulp (libm to 1): a few ulp per factor, 32 ulp of 1 in all
ROUNDING = 32 * np.finfo(float).eps
#: PROJ's ECEF -> geodetic is one Bowring step, whose height error grows as h^2: 6 mm at 830 km (test_geodesy)
PROJ_DRIFT_PER_M2 = 6e-3 / 830e3**2


def rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def ry(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def rz(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def orbital(p, v):
    z = p / np.linalg.norm(p)
    x = np.cross(v, p)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def some_corrections():
    return Corrections(
        position=RNG.normal(0, 5, (3, 4)), attitude=RNG.normal(0, 1e-5, (3, 4)), look=RNG.normal(0, 1e-5, (2, 4))
    )


# -- frames -------------------------------------------------------------------------------------


def test_frames_against_numpy():
    for yaw, pitch, roll in RNG.normal(0, 0.3, (5, 3)):
        np.testing.assert_allclose(frames.r21(yaw, pitch, roll), rx(-pitch) @ ry(-roll) @ rz(yaw), atol=ROUNDING)
    p, v = np.array([1e6, -2e6, 6.8e6]), np.array([7e3, 1e3, 900.0])
    m = frames.r32(*p, *v)
    np.testing.assert_allclose(m, orbital(p, v), atol=ROUNDING)
    np.testing.assert_allclose(m.T @ m, np.eye(3), atol=ROUNDING)
    a, b = frames.r21(0.1, 0.2, 0.3), frames.r32(*p, *v)
    np.testing.assert_allclose(
        np.reshape(frames.mat_mul(tuple(b.ravel()), tuple(a.ravel())), (3, 3)), b @ a, atol=ROUNDING
    )


def test_look_vector_and_angles_are_inverse():
    psi_x, psi_y = 0.01, -0.2
    u = np.array(frames.look_vector(psi_x, psi_y))
    np.testing.assert_allclose(u, [-np.tan(psi_y), np.tan(psi_x), -1.0])
    assert frames.look_angles(*(3.7 * u)) == pytest.approx((psi_x, psi_y), abs=1e-15)
    p, v = np.array([1e6, -2e6, 6.8e6]), np.array([7e3, 1e3, 900.0])
    d = frames.look_direction_ecef(psi_x, psi_y, 1e-3, -2e-3, 3e-3, *p, *v)
    np.testing.assert_allclose(
        d, orbital(p, v) @ rx(2e-3) @ ry(-3e-3) @ rz(1e-3) @ u / np.linalg.norm(u), atol=ROUNDING
    )
    assert frames.ecef_to_look_angles(*d, 1e-3, -2e-3, 3e-3, *p, *v) == pytest.approx((psi_x, psi_y), abs=1e-14)


# -- interpolation ------------------------------------------------------------------------------


def lagrange_reference(ts, ys, t):
    out = 0.0
    for j in range(len(ts)):
        out = out + ys[j] * np.prod([(t - ts[m]) / (ts[j] - ts[m]) for m in range(len(ts)) if m != j])
    return out


def test_lagrange_window_and_kernel_against_product_formula():
    o = synthetic_orientation()
    eph = lagrange_window(o.eph_t, o.eph_pos, o.eph_vel, 10.0)
    assert list(eph[:, 0]) == [-90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0, 120.0]  # 8 nearest to t = 10 s
    for t in (-3.3, 0.0, 7.77, 30.0):
        want = lagrange_reference(eph[:, 0], np.hstack([eph[:, 2:5], eph[:, 5:8]]), t)
        np.testing.assert_allclose(k.lagrange(eph, t), want, rtol=1e-13, atol=1e-7)


def test_attitude_interpolation_against_np_interp():
    o = synthetic_orientation()
    for t in (-10.0, -4.0, -1.234, 0.0625, 3.99, 10.0):
        want = [np.interp(t, o.att_t, o.att_ypr[:, i]) for i in range(3)]
        np.testing.assert_allclose(k.attitude(o.att_t, o.att_ypr, t), want, rtol=0, atol=1e-18)


def test_integrated_attitude():
    """Constant rates give a linear attitude whose constant is fitted to the absolute angles."""
    speed_t = np.arange(0.0, 5.01, 0.5)
    speeds = np.tile([1e-6, -2e-6, 3e-6], (speed_t.size, 1))
    angle_t = np.array([-0.5, 5.5])
    angles = np.array([[0.0, 1e-6, 0.0], [6e-6, -11e-6, 18e-6]]) + 1e-7  # consistent with the rates
    t, a = integrated_attitude(angle_t, angles, speed_t, speeds)
    np.testing.assert_array_equal(t, np.union1d(speed_t, angle_t))
    np.testing.assert_allclose(a, angles[0] + np.outer(t + 0.5, speeds[0]), atol=1e-15)


def test_detector_angles_and_their_inverse():
    look = np.column_stack([np.linspace(1e-3, 2e-3, 5), np.array([-0.03, -0.01, 0.0, 0.02, 0.05])])
    prm = np.array([0.0, 0.0, 1e-3, 10.0, 2.5])
    corr = np.zeros((8, 4))
    for col in (-1.0, 0.5, 1.25, 3.0, 4.5, 6.0):
        x = col - 0.5  # detector index
        if 0 <= x <= 4:
            want = [np.interp(x, np.arange(5), look[:, i]) for i in range(2)]
        else:  # beyond the end detectors the end segments continue
            a = 0 if x < 0 else 3
            want = [look[a, i] + (x - a) * (look[a + 1, i] - look[a, i]) for i in range(2)]
        np.testing.assert_allclose(k.detector_angles(look, prm, corr, col), want, atol=1e-17)
    corr[6] = [1e-5, 2e-6, 0, 1e-7]
    corr[7] = [2e-4, -1e-4, 3e-5, 1e-6]
    for col in (0.6, 1.7, 3.3, 4.4):
        q = (col - 2.5) / 1000
        psi_y = np.interp(col - 0.5, np.arange(5), look[:, 1]) + np.polyval(corr[7][::-1], q)
        assert k.detector_angles(look, prm, corr, col)[1] == pytest.approx(psi_y, abs=1e-17)
        assert k.column_of(look, prm, corr, psi_y) == pytest.approx(col, abs=1e-9)


# -- geodesy along rays ------------------------------------------------------------------------


def test_bowring_matches_proj_near_the_surface():
    lon, lat, h = (
        v.ravel() for v in np.meshgrid([-170.0, 3.0, 100.0], np.linspace(-89.0, 89.0, 19), [-1000.0, 0.0, 9000.0, 1e5])
    )
    xyz = geodetic_to_ecef(lon, lat, h)
    srs = [osr.SpatialReference(), osr.SpatialReference()]
    srs[0].ImportFromEPSG(4978)
    srs[1].ImportFromEPSG(4979)
    for s in srs:
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    reference = np.array(osr.CoordinateTransformation(*srs).TransformPoints(xyz))
    for (x, y, z), (_, lat_ref, h_ref), h_in in zip(xyz, reference, h):
        cl, sl, hh = k.bowring(np.hypot(x, y), z)
        tolerance = 1e-6 + 10 * PROJ_DRIFT_PER_M2 * h_in**2  # rounding, and ten times PROJ's one-step drift
        assert hh == pytest.approx(h_ref, abs=tolerance)
        assert np.degrees(np.arctan2(sl, cl)) == pytest.approx(lat_ref, abs=tolerance / 1.1e5)


@pytest.mark.parametrize("h", [-500.0, 0.0, 4321.0, 9000.0])
def test_ray_height_lands_at_the_height_on_the_ray(h):
    p = np.array([4.0e6, 1.0e6, 5.8e6])
    u = -p / np.linalg.norm(p) + [0.05, -0.1, 0.02]
    u /= np.linalg.norm(u)
    x, y, z, lon, lat = k.ray_height(*p, *u, h)
    point = np.array([x, y, z])
    mu = np.dot(point - p, u)
    np.testing.assert_allclose(point, p + mu * u, atol=1e-6)
    lon_ref, lat_ref, h_ref = (float(v) for v in ecef_to_geodetic(point))
    assert (lon, lat) == pytest.approx((lon_ref, lat_ref), abs=1e-10)  # 10 micrometres
    assert h_ref == pytest.approx(h, abs=1e-6)
    # the first intersection: the same height is not met nearer the satellite
    g = lambda m: ecef_to_geodetic(p + m * u)[2] - h
    assert mu == pytest.approx(brentq(g, 0.5 * mu, 1.0001 * mu, xtol=1e-7), abs=1e-5)
    assert np.isnan(k.ray_height(*p, *(-u), h)[0])  # looking away from the Earth


# -- the model against a numpy implementation of the handbook equations ------------------------


def reference_image_to_ecef(o, c, col, row, h):
    """X = P + mu R32 R21 u1 in plain numpy (8-point Lagrange, np.interp, brentq on the height)."""
    t = o.centre_time + (row - o.centre_row) * o.line_period
    idx = np.sort(np.argsort(np.abs(o.eph_t - o.centre_time))[:8])
    tau = (t - o.centre_time) / c.time_scale
    p = lagrange_reference(o.eph_t[idx], o.eph_pos[idx], t) + [np.polyval(r[::-1], tau) for r in c.position]
    v = lagrange_reference(o.eph_t[idx], o.eph_vel[idx], t) + [
        np.polyval(np.polyder(r[::-1]), tau) / c.time_scale for r in c.position
    ]
    yaw, pitch, roll = [np.interp(t, o.att_t, o.att_ypr[:, i]) + np.polyval(c.attitude[i][::-1], tau) for i in range(3)]
    q = (col - o.ncols / 2) / 1000
    psi_x = np.interp(col - 0.5, np.arange(o.ncols), o.psi_x) + np.polyval(c.look[0][::-1], q)
    psi_y = np.interp(col - 0.5, np.arange(o.ncols), o.psi_y) + np.polyval(c.look[1][::-1], q)
    u = orbital(p, v) @ rx(-pitch) @ ry(-roll) @ rz(yaw) @ [-np.tan(psi_y), np.tan(psi_x), -1.0]
    u /= np.linalg.norm(u)
    mu = brentq(lambda m: ecef_to_geodetic(p + m * u)[2] - h, 1e5, 2e6, xtol=1e-8)
    return p + mu * u


@pytest.mark.parametrize("corrected", [False, True])
def test_image_to_ground_matches_the_numpy_reference(corrected):
    o = synthetic_orientation()
    if corrected:
        o.corrections = some_corrections()
    model = SpotModel(o)
    for col, row, h in [(0.5, 0.5, 0.0), (150.0, 100.0, 2000.0), (299.5, 3.3, -400.0), (17.2, 199.5, 8800.0)]:
        lon, lat = model.image_to_ground(col, row, h)
        want = reference_image_to_ecef(o, o.corrections, col, row, h)
        assert np.linalg.norm(geodetic_to_ecef(lon, lat, h) - want) < 1e-5


def test_line_of_sight_matches_the_numpy_reference():
    o = synthetic_orientation()
    pos, direction = SpotModel(o).line_of_sight([10.5, 200.0], [20.0, 150.0])
    for p, u, (col, row) in zip(pos, direction, [(10.5, 20.0), (200.0, 150.0)]):
        x = reference_image_to_ecef(o, o.corrections, col, row, 0.0)
        np.testing.assert_allclose(u, (x - p) / np.linalg.norm(x - p), atol=1e-12)


@pytest.mark.parametrize("mission", [5, 2])
def test_ground_to_image_inverts_image_to_ground_with_corrections(mission):
    o = synthetic_orientation(mission)
    o.corrections = some_corrections()
    model = SpotModel(o)
    c, r, h = (v.ravel() for v in np.meshgrid(np.linspace(-20, 320, 9), np.linspace(-10, 210, 7), [-500.0, 9000.0]))
    col, row = model.ground_to_image(*model.image_to_ground(c, r, h), h)
    assert np.abs(col - c).max() < 1e-6 and np.abs(row - r).max() < 1e-6


def test_ground_to_image_gives_nan_for_impossible_points():
    model = SpotModel(synthetic_orientation())
    col, row = model.ground_to_image([0.0, 13.0], [-80.0, 39.7], [0.0, 0.0])  # other side of the Earth
    assert np.isnan(col[0]) and np.isfinite(col[1])


def test_image_to_ground_never_extrapolates_the_orbit():
    """Rows whose time lies outside the Lagrange window (-90..120 s here) give NaN, as do heights
    inside the Earth; rows far outside the image but inside the window are still located."""
    model = SpotModel(synthetic_orientation())  # 0.025 s per line, row 100 at t = 0.25 s
    lon, lat = model.image_to_ground([150.0] * 4, [-3000.0, -3700.0, 4700.0, 100.0], [0.0, 0.0, 0.0, -4e6])
    assert np.isfinite(lon[[0, 2]]).all() and np.isnan(lon[[1, 3]]).all() and np.isnan(lat[[1, 3]]).all()
    pos, direction = model.line_of_sight(150.0, 1e6)
    assert np.isnan(pos).all() and np.isnan(direction).all()


def test_scalars_in_floats_out_and_shapes_kept():
    model = SpotModel(synthetic_orientation())
    lon, lat = model.image_to_ground(10, 20, 0)
    assert type(lon) is float and type(lat) is float
    col, row = model.ground_to_image(lon, lat, 0.0)
    assert type(col) is float and col == pytest.approx(10, abs=1e-6)
    lon, lat = model.image_to_ground(np.zeros((2, 3)), 5.0, 0.0)
    assert lon.shape == (2, 3)
    with pytest.raises(InputError, match="one shape"):
        model.image_to_ground(np.zeros(3), np.zeros(4), 0.0)
    with pytest.raises(InputError, match="real numbers"):
        model.ground_to_image("13.0", "forty", 0.0)


def test_drift_switch_for_spot_1_to_4():
    o = synthetic_orientation(2)
    on, off = SpotModel(o), SpotModel(o, drift=False)
    assert on.drift and not off.drift
    np.testing.assert_array_equal(off._att_v, np.zeros((1, 3)))
    lon_on, _ = on.image_to_ground(150.0, 100.0, 0.0)
    lon_off, _ = off.image_to_ground(150.0, 100.0, 0.0)
    assert lon_on != lon_off


# -- partial derivatives ------------------------------------------------------------------------


def test_partials_match_plain_finite_differences():
    o = synthetic_orientation()
    o.corrections = some_corrections()
    model = SpotModel(o)
    c, r = np.meshgrid([5.0, 150.0, 290.0], [10.0, 190.0])
    h = np.full(c.size, 700.0)
    lon, lat = model.image_to_ground(c.ravel(), r.ravel(), h)
    got = model.partials(lon, lat, h)
    np.testing.assert_allclose(got["col"], c.ravel(), atol=1e-6)
    coefficients = [o.corrections.position, o.corrections.attitude, o.corrections.look]
    steps = [5.0] * 12 + [1e-5] * 20
    for index, step in enumerate(steps):
        array = coefficients[min(index // 12, 1) if index < 24 else 2]
        i, j = divmod(index % 12 if index < 24 else index - 24, 4)
        saved = array[i, j]
        array[i, j] = saved + step
        plus = np.array(model.ground_to_image(lon, lat, h))
        array[i, j] = saved - step
        minus = np.array(model.ground_to_image(lon, lat, h))
        array[i, j] = saved
        np.testing.assert_allclose(
            got["d_corrections"][:, :, index],
            ((plus - minus) / (2 * step)).T,
            rtol=1e-4,
            atol=1e-4 / step,
            err_msg=f"coefficient {index}",
        )
    for i, step in enumerate((1e-5, 1e-5, 10.0)):
        args = [lon, lat, h]
        args[i] = args[i] + step
        plus = np.array(model.ground_to_image(*args))
        args[i] = args[i] - 2 * step
        minus = np.array(model.ground_to_image(*args))
        np.testing.assert_allclose(got["d_ground"][:, :, i], ((plus - minus) / (2 * step)).T, rtol=1e-4, atol=1e-5)
    # without the exterior orientation: the same look-angle and ground partials, zeros for position/attitude
    look_only = model.partials(lon, lat, h, exterior=False)
    assert model.EXTERIOR_COEFFICIENTS == 24
    assert np.all(look_only["d_corrections"][:, :, :24] == 0.0)
    for key in ("col", "row", "d_ground", "d_ecef"):
        np.testing.assert_array_equal(look_only[key], got[key])
    np.testing.assert_array_equal(look_only["d_corrections"][:, :, 24:], got["d_corrections"][:, :, 24:])


# -- DEM intersection ---------------------------------------------------------------------------


def rugged_dem():
    """0-3000 m of ridges and a 1 km cliff over the synthetic footprint (0.005 degree cells)."""
    lon = np.arange(12.3, 13.3, 0.005) + 0.0025
    lat = np.arange(40.1, 39.4, -0.005) - 0.0025
    x, y = np.meshgrid(lon, lat)
    z = 1500 + 1000 * np.sin(x * 40) * np.cos(y * 30) + 1000 * (x > 12.8)
    return Dem(z, (12.3, 0.005, 0.0, 40.1, 0.0, -0.005))


def test_image_to_dem_matches_the_generic_method_and_lies_on_dem_and_ray():
    model = SpotModel(synthetic_orientation())
    dem = rugged_dem()
    c, r = (v.ravel() for v in np.meshgrid(np.linspace(0, 300, 16), np.linspace(0, 200, 11)))
    lon, lat, h = model.image_to_dem(c, r, dem)
    lon0, lat0, h0 = SensorModel.image_to_dem(model, c, r, dem)
    assert np.abs(h - h0).max() < 0.01
    assert np.abs(geodetic_to_ecef(lon, lat, h) - geodetic_to_ecef(lon0, lat0, h0)).max() < 0.05
    assert np.abs(h - dem.height(lon, lat)).max() < 1e-3
    col, row = model.ground_to_image(lon, lat, h)
    assert max(np.abs(col - c).max(), np.abs(row - r).max()) < 1e-4


def test_image_to_dem_outside_the_dem_raises():
    model = SpotModel(synthetic_orientation())
    with pytest.raises(GeometryError, match="does not meet the DEM"):
        model.image_to_dem([0.0, 5000.0], [0.0, 0.0], rugged_dem())


def oblique_model():
    """The synthetic scene pointed 26 degrees across track: rays advance 0.5 m per metre of height."""
    o = synthetic_orientation()
    o.psi_y = o.psi_y + 0.45
    return SpotModel(o)


def first_crossing(model, col, row, dem, step=0.25):
    """Brute force: the highest height of a 0.25 m scan down the ray that lies on or below the DEM."""
    hs = np.arange(dem.height_range[1] + 1.0, dem.height_range[0] - 1.0, -step)
    lon, lat = model.image_to_ground(np.full(hs.size, col), np.full(hs.size, row), hs)
    below = np.flatnonzero(hs - dem.height(lon, lat) <= 0)
    return hs[below[0]]


@pytest.mark.parametrize("height", [300.0, 700.0, 1100.0, 1500.0, 1900.0, 2300.0])
def test_image_to_dem_returns_the_first_intersection_with_a_needle(height):
    """A one-cell (13 m) needle of 10 km on flat ground, in the cell where the ray passes `height`:
    the scan must not step over it (64 fixed height steps advance 80 m per step on this oblique ray,
    the needle's bilinear cone is 26 m wide at its foot)."""
    model = oblique_model()
    col, row = 150.0, 100.0
    lon0, lat0 = model.image_to_ground(col, row, 0.0)
    cell = 0.00015
    lons = np.arange(lon0 - 0.03, lon0 + 0.03, cell)
    lats = np.arange(lat0 + 0.03, lat0 - 0.03, -cell)
    z = np.zeros((lats.size, lons.size))
    lon_n, lat_n = model.image_to_ground(col, row, height)
    z[int((lats[0] + cell / 2 - lat_n) / cell), int((lon_n - lons[0] + cell / 2) / cell)] = 10000.0
    dem = Dem(z, (lons[0] - cell / 2, cell, 0.0, lats[0] + cell / 2, 0.0, -cell))
    want = first_crossing(model, col, row, dem)
    assert want >= height  # the ray meets the needle, at or above `height`
    for method in (model.image_to_dem, lambda c, r, d: SensorModel.image_to_dem(model, c, r, d)):
        lon, lat, h = method(col, row, dem)
        assert h == pytest.approx(want, abs=0.5)
        assert h == pytest.approx(dem.height(lon, lat), abs=1e-3)


def test_image_to_dem_meets_a_cliff_face_not_the_plateau_behind_it():
    """Rays looking at a 3000 m cliff face from the low side hit the face, at the brute-force height."""
    model = oblique_model()
    lon0, lat0 = model.image_to_ground(150.0, 100.0, 0.0)
    lon_top, _ = model.image_to_ground(150.0, 100.0, 3000.0)
    cell = 0.0003
    lons = np.arange(lon0 - 0.05, lon0 + 0.05, cell)
    lats = np.arange(lat0 + 0.05, lat0 - 0.05, -cell)
    x, _ = np.meshgrid(lons, lats)
    edge = 0.5 * (lon0 + lon_top)  # the ray passes the cliff edge at about 1500 m
    # plateau beyond the edge, its face turned to the satellite
    z = np.where((x - edge) * np.sign(lon_top - lon0) < 0, 3000.0, 0.0)
    dem = Dem(z, (lons[0] - cell / 2, cell, 0.0, lats[0] + cell / 2, 0.0, -cell))
    cols = np.array([149.9, 150.0, 150.1])  # 20 m apart on the ground
    lon, lat, h = model.image_to_dem(cols, np.full(3, 100.0), dem)
    for c, got in zip(cols, h):
        assert got == pytest.approx(first_crossing(model, c, 100.0, dem), abs=0.5)
    assert np.all((h > 100.0) & (h < 2900.0))  # on the face, neither on top nor at its foot
