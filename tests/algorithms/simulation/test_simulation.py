"""Scene simulator, part by part: numba kernels against plain numpy references on tiny data, the
orbit, the truth geometry against the SPOT model of its sampled orientation, the source DEM's
orientation and the injected errors."""

import math

import numpy as np
import pytest

from pushbroom.algorithms.geodesy import ecef_to_geodetic, geodetic_to_ecef, metres_per_degree
from pushbroom.algorithms.sensors import spot_frames
from pushbroom.algorithms.sensors.spot import SpotModel
from pushbroom.algorithms.simulation import acquisition, noise, orbit, perturbation, radiometry, render, terrain
from pushbroom.algorithms.simulation.grid import Grid
from pushbroom.algorithms.simulation.sun import sun_position

RNG = np.random.default_rng(42)


# ----------------------------------------------------------------------------- numpy references


def bilinear_np(z, x, y):
    """Bilinear interpolation of z at vertex coordinates, NaN outside."""
    rows, cols = z.shape
    inside = (x >= 0) & (x <= cols - 1) & (y >= 0) & (y <= rows - 1)
    j = np.clip(np.floor(np.nan_to_num(x)).astype(int), 0, cols - 2)
    i = np.clip(np.floor(np.nan_to_num(y)).astype(int), 0, rows - 2)
    fx, fy = x - j, y - i
    v = (z[i, j] * (1 - fx) + z[i, j + 1] * fx) * (1 - fy) + (z[i + 1, j] * (1 - fx) + z[i + 1, j + 1] * fx) * fy
    return np.where(inside, v, np.nan)


def first_hit_np(a, b, z, samples=100001):
    """First s of a dense sampling of the segment a -> b at or below the surface (-1 if none)."""
    s = np.linspace(0.0, 1.0, samples)
    p = a[None] + s[:, None] * (b - a)[None]
    below = p[:, 2] <= bilinear_np(z, p[:, 0], p[:, 1])
    return s[np.argmax(below)] if below.any() else -1.0


def rough_surface(rows=40, cols=50):
    z = RNG.normal(0, 3, (rows, cols)).cumsum(0).cumsum(1) * 0.1
    z[10:14, 20:25] += 30.0  # a building
    return z


# ----------------------------------------------------------------------------- render kernels


def test_block_max_matches_numpy():
    z = rough_surface()
    bs = 4
    got = render.block_max(z, bs)
    for bi in range(got.shape[0]):
        for bj in range(got.shape[1]):
            rows = slice(bi * bs, min((bi + 1) * bs, z.shape[0] - 1) + 1)
            cols = slice(bj * bs, min((bj + 1) * bs, z.shape[1] - 1) + 1)
            want = z[rows, cols].max()
            assert got[bi, bj] == want


@pytest.mark.parametrize("upwards", [False, True])
def test_first_hit_matches_dense_sampling(upwards):
    z = rough_surface()
    bmax = render.block_max(z, 4)
    for _ in range(150):
        a = np.array([RNG.uniform(-5, 55), RNG.uniform(-5, 45), 0.0])
        b = a + np.array([RNG.normal(0, 15), RNG.normal(0, 15), 0.0])
        if upwards:  # shadow rays: start just above the surface, climb
            a[:2] = RNG.uniform(1, 38), RNG.uniform(1, 38)
            a[2] = bilinear_np(z, a[:1], a[1:2])[0] + 0.05
            b[2] = a[2] + RNG.uniform(0, 40)
        else:
            a[2], b[2] = z.max() + RNG.uniform(0, 5), z.min() - RNG.uniform(0, 5)
        got = render.first_hit(*a, *b, z, bmax, 4)
        want = first_hit_np(a, b, z)
        assert (got < 0) == (want < 0)
        assert abs(got - want) < 1.5e-5  # the reference's sampling step is 1e-5


def test_near_surface_geodetic_matches_geodesy():
    lon, lat, h = RNG.uniform(-180, 180, 2000), RNG.uniform(-89, 89, 2000), RNG.uniform(-500, 9000, 2000)
    xyz = geodetic_to_ecef(lon, lat, h)
    got = np.array([render.near_surface_geodetic(*p) for p in xyz])
    want = np.column_stack(ecef_to_geodetic(xyz))
    assert np.max(np.abs(got[:, :2] - want[:, :2])) * 111e3 < 1e-6 and np.max(np.abs(got[:, 2] - want[:, 2])) < 1e-6


def test_line_matrices_match_frames():
    pos = RNG.normal(0, 4e6, (5, 3))
    vel = RNG.normal(0, 5e3, (5, 3))
    ypr = RNG.normal(0, 0.01, (5, 3))
    got = render.line_matrices(pos, vel, ypr).reshape(-1, 3, 3)
    for k in range(5):
        want = spot_frames.r32(*pos[k], *vel[k]) @ spot_frames.r21(*ypr[k])
        np.testing.assert_allclose(got[k], want, atol=8 * np.finfo(float).eps)  # a few ulp of a unit 3 x 3 product


def _small_grid_surface(height_fn, lon=-84.2, lat=36.6, half_m=1500.0, cell=10.0):
    me, mn = metres_per_degree(lat)
    grid = Grid.covering((lon - half_m / me, lat - half_m / mn, lon + half_m / me, lat + half_m / mn), cell)
    glon, glat = grid.lonlat(*np.meshgrid(np.arange(grid.cols), np.arange(grid.rows)))
    return grid, render.Surface(grid, height_fn(glon, glat))


@pytest.mark.parametrize("tilted", [False, True])
def test_trace_matches_numpy_ray_intersection(tilted):
    """Rays from 830 km, up to 25 deg off nadir, against a flat or a tilted planar DSM: the kernel's
    ground point (bracketing sphere, linearised ray, DDA) equals a numpy fixed-point iteration of
    the exact ray-height intersection to a centimetre."""

    def plane(lon, lat):
        return 400.0 + (2000.0 * (lon + 84.2) - 1500.0 * (lat - 36.6) if tilted else 0.0 * lon)

    grid, surface = _small_grid_surface(plane)
    target = geodetic_to_ecef(RNG.uniform(-84.21, -84.19, 20), RNG.uniform(36.59, 36.61, 20), np.full(20, 400.0))
    up = target / np.linalg.norm(target, axis=1, keepdims=True)
    tilt = RNG.normal(0, 1, (20, 3))
    tilt -= np.sum(tilt * up, axis=1, keepdims=True) * up
    tilt *= np.tan(np.radians(RNG.uniform(0, 25, 20)))[:, None] / np.linalg.norm(tilt, axis=1, keepdims=True)
    direction = -(up + tilt)
    pos = target - 880e3 * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    eye = np.tile(np.eye(3).ravel(), (20, 1))
    got = surface.trace(pos, eye, direction)
    h = np.full(20, 400.0)
    for _ in range(8):
        lon, lat = acquisition.ray_at_height(pos, direction, h)
        h = plane(lon, lat)
    assert np.max(np.abs(got[:, 2] - h)) < 0.01
    err = np.linalg.norm(geodetic_to_ecef(got[:, 0], got[:, 1], got[:, 2]) - geodetic_to_ecef(lon, lat, h), axis=1)
    assert err.max() < 0.01


def test_render_samples_radiance_where_the_ray_lands():
    grid, surface = _small_grid_surface(lambda lon, lat: 300.0 + 0.0 * lon)
    ramp = np.tile(np.arange(grid.cols, dtype=np.float32), (grid.rows, 1))  # radiance = vertex x
    target = geodetic_to_ecef(np.linspace(-84.205, -84.195, 6), np.full(6, 36.6), np.full(6, 300.0))
    direction = -target / np.linalg.norm(target, axis=1, keepdims=True)
    pos = target - 830e3 * direction
    eye = np.tile(np.eye(3).ravel(), (6, 1))
    image = surface.render(pos, eye, direction, ramp)  # 6 lines x 6 detectors
    ground = surface.trace(pos, eye, direction)
    x, _ = grid.vertex(ground[:, 0], ground[:, 1])
    np.testing.assert_allclose(np.diag(image), x, atol=1e-3)


# ----------------------------------------------------------------------------- terrain kernels


def keys_np(t):
    t = np.abs(t)
    return np.where(t < 1, (1.5 * t - 2.5) * t * t + 1, np.where(t < 2, ((-0.5 * t + 2.5) * t - 4) * t + 2, 0.0))


def test_cubic_resample_matches_numpy():
    src = RNG.normal(size=(6, 7))
    x0, dx, y0, dy = -0.3, 0.37, 0.2, 0.29
    got = terrain.cubic_resample(src, x0, dx, y0, dy, 15, 18)
    ii, jj = np.mgrid[0:15, 0:18]
    x, y = x0 + jj * dx, y0 + ii * dy
    want = np.zeros_like(x)
    for m in range(-1, 3):
        for n in range(-1, 3):
            yi, xi = np.floor(y) + m, np.floor(x) + n
            want += (
                keys_np(y - yi) * keys_np(x - xi) * src[np.clip(yi, 0, 5).astype(int), np.clip(xi, 0, 6).astype(int)]
            )
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_slope_matches_numpy_gradient():
    z = RNG.normal(size=(9, 11)).cumsum(0)
    dzdy, dzdx = np.gradient(z, 4.0, 5.0)
    want = np.degrees(np.arctan(np.hypot(dzdx, dzdy)))
    np.testing.assert_allclose(terrain.slope_degrees(z, 5.0, 4.0), want, atol=1e-4)


def test_fractal_detail_matches_numpy_sum_of_octaves():
    dtm = np.zeros((5, 6))
    terrain._add_fractal(dtm, -10.0, 5.0, 12.0, 4.0, 180.0, 3, 2.0, 0.5, 9)
    want = np.zeros_like(dtm)
    for i in range(5):
        for j in range(6):
            e, n = -10.0 + 5.0 * j, 12.0 - 4.0 * i
            want[i, j] = sum(
                2.0 * 0.5**k * noise.gradient_noise(e * 2**k / 180.0, n * 2**k / 180.0, 9 + 101 * k) for k in range(3)
            )
    np.testing.assert_allclose(dtm, want, atol=1e-12)


def test_nearest_resample_matches_numpy():
    src = RNG.integers(0, 9, (7, 8)).astype(np.uint8)
    got = terrain._nearest(src, -0.4, 0.45, 0.3, 0.6, 11, 16)
    ii, jj = np.mgrid[0:11, 0:16]
    rows = np.clip(np.round(0.3 + ii * 0.6), 0, 6).astype(int)
    cols = np.clip(np.round(-0.4 + jj * 0.45), 0, 7).astype(int)
    want = src[rows, cols]
    np.testing.assert_array_equal(got, want)


def test_worley_matches_brute_force():
    for _ in range(200):
        x, y = RNG.uniform(-50, 50, 2)
        d, cx, cy, _ = noise.worley(x, y, 7, 0.9)
        best = min(
            (
                math.hypot(
                    x - (i + 0.5 + 0.9 * (noise.uniform(i, j, 7) - 0.5)),
                    y - (j + 0.5 + 0.9 * (noise.uniform(i, j, 8) - 0.5)),
                ),
                i,
                j,
            )
            for i in range(int(math.floor(x)) - 2, int(math.floor(x)) + 3)
            for j in range(int(math.floor(y)) - 2, int(math.floor(y)) + 3)
        )
        assert (d, cx, cy) == pytest.approx(best)


def test_gradient_noise_is_deterministic_bounded_and_zero_on_the_lattice():
    xy = RNG.uniform(-100, 100, (500, 2))
    values = np.array([noise.gradient_noise(x, y, 3) for x, y in xy])
    assert np.all(np.abs(values) < 1.0) and values.std() > 0.1
    assert np.array_equal(values, [noise.gradient_noise(x, y, 3) for x, y in xy])
    assert not np.array_equal(values, [noise.gradient_noise(x, y, 4) for x, y in xy])
    assert all(noise.gradient_noise(float(i), float(j), 3) == 0.0 for i, j in RNG.integers(-50, 50, (20, 2)))


# ----------------------------------------------------------------------------- radiometry kernels


def test_illumination_of_an_open_tilted_plane_is_lambertian():
    rows, cols, de, dn = 12, 14, 5.0, 6.0
    ii, jj = np.mgrid[0:rows, 0:cols]
    z = 100.0 + 0.2 * jj * de + 0.1 * (-ii * dn)  # dz/de = 0.2, dz/dnorth = 0.1 (rows run south)
    az, el = math.radians(250.0), math.radians(50.0)  # the slope faces west-south-west: lit
    got = radiometry.illumination(z, render.block_max(z, render.BLOCK), de, dn, az, el, z.max(), 0, rows, 0, cols)
    normal = np.array([-0.2, -0.1, 1.0]) / math.sqrt(1.05)
    sun = np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])
    want = radiometry.E_DIRECT * normal @ sun + radiometry.E_SKY * 0.5 * (1 + normal[2])
    np.testing.assert_allclose(got, want, rtol=1e-6)


def test_cast_shadow_of_a_block_matches_numpy_ray_march():
    z = np.zeros((40, 40))
    z[18:22, 18:22] = 20.0
    de = dn = 2.0
    az, el = math.radians(135.0), math.radians(40.0)  # sun in the south-east: shadow north-west
    bmax = render.block_max(z, render.BLOCK)
    lit = radiometry.illumination(z, bmax, de, dn, az, el, z.max(), 0, 40, 0, 40) > radiometry.E_SKY + 1e-6
    gx, gy = math.sin(az) / de, -math.cos(az) / dn
    for i in range(40):
        for j in range(40):
            length = (z.max() - z[i, j]) / math.tan(el) + 1.0
            a = np.array([j, i, z[i, j] + 0.05])
            b = a + length * np.array([gx, gy, math.tan(el)])
            shadow = first_hit_np(a, b, z, 4001) >= 0
            if (i, j) not in {(r, c) for r in range(17, 23) for c in range(17, 23)}:  # block walls
                assert lit[i, j] == (not shadow), (i, j)
    assert not lit[14, 14] and lit[25, 25]  # north-west of the block shaded, south-east lit


def test_reflectance_classes_and_textures():
    rows, cols = 60, 60
    feature = np.arange(rows * cols).reshape(rows, cols) // 300
    objects = np.full((rows, cols), 20.0)
    out = {}
    for c in (terrain.WATER, terrain.BARE, terrain.CROPS, terrain.FOREST, terrain.CITY):
        classes = np.full((rows, cols), c, np.uint8)
        out[c] = radiometry.reflectance(
            classes, feature if c != terrain.CITY else feature + 2, objects, 0.0, 5.0, 0.0, 5.0, 1
        )
        assert np.all((out[c] > 0) & (out[c] < 1))
    assert out[terrain.WATER].mean() < 0.05 and out[terrain.WATER].std() < 0.003  # low texture
    assert out[terrain.BARE].std() > 3 * out[terrain.WATER].std()


def test_sensor_image_quantisation_and_nodata():
    radiance = np.full((20, 30), 0.3, np.float32)
    radiance[5, 5] = np.nan
    dn = radiometry.sensor_image(radiance, 450.0, 12.0, 0.0, 12, np.random.default_rng(0))
    assert dn.dtype == np.uint16 and dn[5, 5] == 0
    assert dn[15, 20] == round(16 * (450 * 0.3 + 12))
    dn8 = radiometry.sensor_image(radiance * 10, 450.0, 12.0, 2.0, 8, np.random.default_rng(0))
    assert dn8.dtype == np.uint8 and dn8.max() == 255 and dn8[5, 5] == 0


# ----------------------------------------------------------------------------- orbit and truth


def test_orbit_is_sun_synchronous_circular_and_consistent():
    o = orbit.CircularOrbit(node_lon=-1.0, u0=2.0, t0=100.0)
    assert math.degrees(o.inclination) == pytest.approx(98.7, abs=0.05)
    t = np.linspace(0.0, 300.0, 31)
    pos, vel = o.state(t)
    _, lat, h = ecef_to_geodetic(pos)
    assert np.all((h > 815e3) & (h < 845e3))
    dt = 1e-3
    numeric = (o.state(t + dt)[0] - o.state(t - dt)[0]) / (2 * dt)
    np.testing.assert_allclose(vel, numeric, atol=1e-5)
    att = orbit.Attitude.random(np.random.default_rng(1), 100.0)
    numeric = (att.angles(t + dt) - att.angles(t - dt)) / (2 * dt)
    np.testing.assert_allclose(att.rates(t), numeric, atol=1e-12)


def test_sun_position_matches_spot5_metadata():
    az, el = sun_position(np.datetime64("2005-03-13T05:21:07"), 87.921433, 49.953937)
    assert az == pytest.approx(162.435, abs=0.1)  # SUN_AZIMUTH of the real spot5_hrg1_2005 scene
    assert el == pytest.approx(35.25, abs=0.6)  # SUN_ELEVATION (SPOT's own definition differs slightly)


@pytest.fixture(scope="module")
def source():
    return terrain.jacksboro_dem()


@pytest.mark.parametrize(
    "configuration,dates,roll",
    [("spot5_triplet", ("2005-05-17",), (0.0,)), ("spot14_pair", ("1999-07-10", "1999-07-13"), (12.0, -12.0))],
)
def test_truth_matches_spot_model_of_sampled_orientation(source, configuration, dates, roll):
    """The continuous truth and the rigorous model of its sampled orientation agree to 1e-3 px,
    the ephemeris has >= 4 samples beyond each end, the attitude 8 Hz samples."""
    lon, lat = source.centre
    images = acquisition.plan(configuration, (lon, lat, 400.0), 5000.0, dates, roll, np.random.default_rng(3))
    for image in images:
        o = image.orientation()
        first, last = image.time_span()
        assert np.sum(o.eph_t <= first) >= 4 and np.sum(o.eph_t >= last) >= 4
        assert np.diff(o.eph_t) == pytest.approx(image.instrument.ephemeris_step)
        rate_t = o.att_t if o.mission == 5 else o.speed_t
        assert np.diff(rate_t) == pytest.approx(0.125)
        model = SpotModel(o)
        c = RNG.uniform(0, image.ncols, 30)
        r = RNG.uniform(0, image.nrows, 30)
        h = RNG.uniform(200, 1100, 30)
        glon, glat = model.image_to_ground(c, r, h)
        tc, tr = image.ground_to_image(geodetic_to_ecef(glon, glat, h))
        assert np.max(np.abs(tc - c)) < 1e-3 and np.max(np.abs(tr - r)) < 1e-3


def test_acquisition_geometry(source):
    lon, lat = source.centre
    images = acquisition.plan(
        "spot5_triplet", (lon, lat, 400.0), 5000.0, ("2005-05-17",), (0.0,), np.random.default_rng(3)
    )
    hrg, hrs1, hrs2 = images
    assert 35 < hrg.centre_time - hrs1.centre_time < 55 and 35 < hrs2.centre_time - hrg.centre_time < 55
    centre = geodetic_to_ecef(lon, lat, 400.0)
    for image in images:  # the scene centre is imaged at the image centre
        col, row = image.ground_to_image(centre)
        assert abs(col[0] - image.ncols / 2) < 1e-3 and abs(row[0] - image.nrows / 2) < 1e-3
    p1, p2 = hrs1.orbit.state(hrs1.centre_time)[0], hrs2.orbit.state(hrs2.centre_time)[0]
    assert np.linalg.norm(p1 - p2) / (np.linalg.norm(p1) - np.linalg.norm(centre)) == pytest.approx(0.8, abs=0.05)
    assert hrg.ncols == 1000 and hrs1.ncols == 500 and hrs1.nrows == pytest.approx(1000, abs=10)


# ----------------------------------------------------------------------------- source DEM and terrain


def test_jacksboro_dem_is_north_up(source):
    """USGS facts: Norris Lake (the flat 305 m reservoir, the tile's lowest ground) lies in the
    south-east, and the Cumberland Mountains (the highest ground) rise west of it."""
    lon0, dlon, _, lat0, _, dlat = source.geotransform
    assert dlat < 0 and lat0 == pytest.approx(36.7329, abs=1e-4)  # row 0 is the north edge
    rows, cols = np.nonzero(source.lake)
    lake_lon, lake_lat = lon0 + (cols.mean() + 0.5) * dlon, lat0 + (rows.mean() + 0.5) * dlat
    centre_lon, centre_lat = source.centre
    assert lake_lat < centre_lat and lake_lon > centre_lon
    top = np.argwhere(source.heights >= np.percentile(source.heights, 99.5))
    assert lon0 + (top[:, 1].mean() + 0.5) * dlon < lake_lon - 0.05
    assert source.geoid.mean() == pytest.approx(-30.8, abs=1.0)  # EGM96 in eastern Tennessee


def test_terrain_classes_objects_and_water(source):
    """On a coarse grid over the whole DEM: objects only on forest and city, water flat at the
    lake level (+ geoid), heights ellipsoidal."""
    lon_min, lat_min, lon_max, lat_max = source.bounds
    grid = Grid.covering((lon_min + 0.003, lat_min + 0.003, lon_max - 0.003, lat_max - 0.003), 40.0)
    t = terrain.build_terrain(source, grid, seed=5)
    d = t.dsm - t.dtm
    on = np.isin(t.classes, (terrain.FOREST, terrain.CITY))
    assert np.all(d[~on] == 0) and d[t.classes == terrain.FOREST].min() > 5
    assert d[t.classes == terrain.CITY].max() > 10
    water = t.classes == terrain.WATER
    assert water.sum() > 1000 and np.ptp(t.dtm[water]) < 1.0
    assert t.dtm[water].mean() == pytest.approx(terrain.LAKE_LEVEL - 30.8, abs=1.0)
    assert set(np.unique(t.classes)) == {1, 2, 3, 4, 5}
    flat = terrain.build_terrain(source, grid, seed=5, surface_objects=False)
    assert np.array_equal(flat.dsm, flat.dtm) and np.array_equal(flat.classes, t.classes)


# ----------------------------------------------------------------------------- injected errors


def test_injected_errors_follow_table2_and_are_common_to_the_trajectory(source):
    lon, lat = source.centre
    images = acquisition.plan(
        "spot5_triplet", (lon, lat, 400.0), 5000.0, ("2005-05-17",), (0.0,), np.random.default_rng(3)
    )
    corrections, passes = perturbation.inject(images, np.random.default_rng(4))
    hrg, hrs1, hrs2 = (corrections[i.name] for i in images)
    assert np.abs(hrg.look) == pytest.approx(np.array([[2.8e-5, 0, 0, 0], [5.3e-6, 1.0e-6, 0, 0]]))
    assert np.abs(hrs2.look[0]) == pytest.approx([0, 0, 4.6e-7, 7.4e-8])
    assert np.array_equal(hrg.position, hrs1.position) and np.linalg.norm(hrg.position[:, 0]) == pytest.approx(8.0)
    # attitude polynomials of the three images are one trajectory polynomial
    t = images[1].centre_time + 3.0
    value = [
        np.polynomial.polynomial.polyval((t - i.centre_time) / 10.0, corrections[i.name].attitude.T) for i in images
    ]
    np.testing.assert_allclose(value[0], value[1], atol=1e-15)
    np.testing.assert_allclose(value[0], value[2], atol=1e-15)


@pytest.mark.slow
def test_ground_psf_filter_matches_the_pixel_psf_integral():
    """One ray per pixel on the radiance pre-filtered by the ground-projected PSF equals the PSF
    integral over 3 x 3 rays per pixel (scene._integrate) on flat ground and on the bare terrain
    (image signal about 34 DN; the quadrature itself is good to a few tenths of a DN)."""
    from pushbroom.algorithms.simulation import scene
    from pushbroom.algorithms.simulation.render import Surface

    config = scene.SceneConfig.small().resolved()
    source = terrain.jacksboro_dem()
    images, grid, centre = scene._plan(config, source)
    ground = terrain.build_terrain(source, grid, config.seed, config.fractal, config.surface_objects)
    candidates, surface = scene._candidates(config, ground, images)
    radiance, _ = scene._radiance(config, ground, surface, images, candidates, centre)
    height = 0.5 * (surface.hmin + surface.hmax)
    flat = Surface(grid, np.full_like(ground.dsm, height))
    bare = Surface(grid, ground.dtm)
    for image in images:
        rad = radiance[image.instrument.pass_index]
        for surf in (flat, bare):
            fast = surf.render(
                *image.line_geometry(), image.look_vectors(), scene.ground_psf_filter(image, grid, height, rad)
            )
            slow = scene._integrate(image, surf, rad)
            d = radiometry.NOMINAL_GAIN * (fast - slow)
            assert np.sqrt(np.mean(d * d)) < 1.0, image.name
            assert np.percentile(np.abs(d), 99) < 3.0, image.name


def test_the_shortfall_of_candidates_and_blunders_is_told_with_its_numbers():
    from pushbroom.algorithms.simulation.points import Candidates, shortfall

    three = np.zeros(3)
    made = Candidates(
        three,
        three,
        three,
        {},
        {"A": np.zeros((3, 2)), "B": np.zeros((3, 2))},
        {"A": np.array([True, True, False]), "B": np.array([True, True, True])},
    )
    assert shortfall(3, 3, made, 5, 400.0, 40.0) is None  # all asked for were made
    text = shortfall(9, 4, made, 8, 400.0, 40.0)
    # 9 asked, 4 sites found, one hidden from an image; 8 blunders asked, 6 measurements to take them
    assert text.startswith(
        "3 control/check point candidates made of the 9 asked: the scene holds 4 sites of open, "
        "flat ground (bare soil or crops 40 m around, inside every image) at least 400 m apart, "
        "and 1 of them is hidden from an image"
    )
    assert text.endswith(
        "5 blunders made of the 8 asked: the 3 candidates have 6 image measurements, and a "
        "measurement takes one blunder at most"
    )
