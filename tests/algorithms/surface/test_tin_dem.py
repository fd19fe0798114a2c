"""DEM from a point cloud (algorithms/surface/tin_dem.py, tin.py, tin_grid.py): the numba rasteriser
against scipy's LinearNDInterpolator, gaps, breaklines, the blunder filter, datum and CRS, writing."""

import numpy as np
import pytest
from osgeo import gdal, osr
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import Delaunay

from pushbroom.algorithms.crs import egm96_undulation, srs
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.surface import geotiff, point_input, pointcloud, tin, tin_dem
from pushbroom.algorithms.surface.tin_grid import Grid, rasterize
from tests.helpers.feedback import Feedback
from tests.helpers.osr_oracle import utm

UTM31 = 32631
X0, Y0 = 640_000.0, 4_890_000.0  # near Mont Ventoux, UTM 31N


def cloud(n, seed=0, size=2000.0, noise=0.0):
    """n random points over a size x size m square of hilly terrain (z ellipsoidal)."""
    rng = np.random.default_rng(seed)
    x, y = X0 + rng.uniform(0, size, n), Y0 + rng.uniform(0, size, n)
    z = 500 + 80 * np.sin((x - X0) / 300) * np.cos((y - Y0) / 400) + rng.normal(0, noise, n) * (noise > 0)
    return x, y, z


def reference(x, y, z, grid):
    """scipy's LinearNDInterpolator at the cell centres (coordinates shifted to the points' mean, as
    tin.delaunay does for qhull's precision, so both triangulate the same way)."""
    mx, my = np.mean(x), np.mean(y)
    cx, cy = grid.centres()
    return LinearNDInterpolator(np.column_stack([x - mx, y - my]), z)(cx - mx, cy - my)


def test_rasterize_matches_linear_nd_interpolator_on_a_known_function():
    x, y, z = cloud(5000, seed=1)
    grid = Grid.covering(x, y, 7.0)
    dem = rasterize(x, y, z, tin.delaunay(x, y).simplices, grid)
    ref = reference(x, y, z, grid)
    np.testing.assert_array_equal(np.isfinite(dem), np.isfinite(ref))
    assert np.isfinite(dem).sum() > 0.9 * dem.size
    np.testing.assert_allclose(dem[np.isfinite(ref)], ref[np.isfinite(ref)], rtol=0, atol=1e-9)


def test_a_plane_is_exact_and_bands_interpolate_together():
    x, y, _ = cloud(400, seed=2, size=500.0)
    plane = 120.0 + 0.3 * (x - X0) - 0.2 * (y - Y0)
    grid = Grid.covering(x, y, 5.0)
    bands = rasterize(x, y, np.column_stack([plane, 2 * plane]), tin.delaunay(x, y).simplices, grid)
    cx, cy = grid.centres()
    inside = np.isfinite(bands[0])
    truth = 120.0 + 0.3 * (cx - X0) - 0.2 * (cy - Y0)
    np.testing.assert_allclose(bands[0][inside], truth[inside], rtol=0, atol=1e-9)
    np.testing.assert_allclose(bands[1][inside], 2 * truth[inside], rtol=0, atol=1e-9)
    assert inside.sum() > 0.8 * inside.size


def test_no_cell_on_a_shared_edge_is_lost():
    """Points on every 4th cell centre: many centres lie exactly on triangle edges and vertices, and
    every one inside the hull (its boundary is either side's) gets the plane's value."""
    i, j = np.meshgrid(np.arange(0, 41, 4), np.arange(0, 41, 4))
    x, y = 0.5 + j.ravel(), 40.5 - i.ravel()
    grid = Grid(0.0, 41.0, 1.0, 41, 41)
    dem = rasterize(x, y, 3 * x + y, tin.delaunay(x, y).simplices, grid)
    cx, cy = grid.centres()
    np.testing.assert_allclose(dem[1:-1, 1:-1], (3 * cx + cy)[1:-1, 1:-1], rtol=0, atol=1e-9)


def test_long_triangles_are_gaps():
    x, y, z = cloud(20000, seed=4)  # ~14 m point spacing
    hole = np.hypot(x - X0 - 1000, y - Y0 - 1000) < 300  # a lake with no points
    x, y, z = x[~hole], y[~hole], z[~hole]
    points = point_input.PointSet(x, y, z, srs(UTM31))
    result = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=10.0, k=0, max_edge=60.0))
    cx, cy = result.grid.centres()
    r = np.hypot(cx - X0 - 1000, cy - Y0 - 1000)
    assert np.isnan(result.heights[r < 250]).all()
    ring = (r > 400) & (r < 800)
    assert np.isfinite(result.heights[ring]).mean() > 0.97
    filled = tin_dem.interpolate_dem(
        points, tin_dem.DemParams(cell=10.0, k=0, max_edge=1e4)
    )  # no gap rule: surface over the lake
    assert np.isfinite(filled.heights[r < 250]).all()


def test_blunder_filter_removes_injected_spikes(figures):
    x, y, z = cloud(20000, seed=5, noise=0.3)
    rng = np.random.default_rng(6)
    spikes = rng.choice(len(x), 200, replace=False)
    z[spikes] += rng.choice([-1, 1], 200) * rng.uniform(8, 60, 200)
    keep, removed = tin.filter_blunders(tin.delaunay(x, y), x, y, z, k=4.0, iterations=3)
    false = int((~keep).sum() - (~keep[spikes]).sum())
    figures.report("spikes removed", (~keep[spikes]).sum(), note="of 200")
    figures.report("clean points removed", false, note=f"of {len(x) - 200}")
    figures.report("removed per iteration", removed)
    assert (~keep[spikes]).all()
    assert false < 0.002 * len(x)
    assert sum(removed) == (~keep).sum()
    fixed = np.zeros(len(x), bool)
    fixed[spikes[:50]] = True  # breakline vertices are never removed
    keep, _ = tin.filter_blunders(tin.delaunay(x, y), x, y, z, fixed=fixed)
    assert keep[spikes[:50]].all() and not keep[spikes[50:]].any()


def test_breaklines_keep_triangles_off_a_ridge():
    """A roof-shaped ridge z = 100 - 0.5 |x - 500|: with the ridge line as breakline the TIN is exact
    on both planes; without it triangles cut the ridge."""
    rng = np.random.default_rng(7)
    x, y = X0 + rng.uniform(0, 1000, 3000), Y0 + rng.uniform(0, 1000, 3000)
    roof = lambda px: 100 - 0.5 * np.abs(px - X0 - 500)
    points = point_input.PointSet(x, y, roof(x), srs(UTM31))
    ridge = np.array([[X0 + 500, Y0 - 10, 100.0], [X0 + 500, Y0 + 1010, 100.0]])
    plain = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=5.0, k=0, max_edge=100.0))
    lined = tin_dem.interpolate_dem(
        points, tin_dem.DemParams(cell=5.0, k=0, max_edge=100.0), breaklines=[ridge], breakline_srs=srs(UTM31)
    )
    cx, _ = lined.grid.centres()
    ok = np.isfinite(lined.heights)
    assert ok.mean() > 0.95 and lined.breakline_vertices > 200
    np.testing.assert_allclose(lined.heights[ok], roof(cx)[ok], atol=1e-9)
    assert np.nanmax(np.abs(plain.heights - roof(cx))) > 0.05
    vertices, segments, keep = tin.conform_breaklines([ridge], x, y, spacing=2.5, min_length=0.25)
    all_x, all_y = np.concatenate([x[keep], vertices[:, 0]]), np.concatenate([y[keep], vertices[:, 1]])
    edges = {
        tuple(sorted(e))
        for s in Delaunay(np.column_stack([all_x - X0, all_y - Y0])).simplices
        for e in ((s[0], s[1]), (s[1], s[2]), (s[0], s[2]))
    }
    offset = int(keep.sum())
    assert all(tuple(sorted(offset + s)) in edges for s in segments)  # every sub-segment is a TIN edge


def test_egm96_datum_and_output_crs():
    x, y, z = cloud(3000, seed=8)
    points = point_input.PointSet(x, y, z, srs(UTM31))
    ellipsoidal = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=20.0, k=0))
    assert ellipsoidal.srs.GetAuthorityCode(None) == str(UTM31)  # default: the points' UTM zone
    geoid = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=20.0, k=0, datum="egm96"))
    ok = np.isfinite(ellipsoidal.heights)
    cx, cy = ellipsoidal.grid.centres()
    t = osr.CoordinateTransformation(srs(UTM31), srs(4326))
    lonlat = np.array([t.TransformPoint(float(a), float(b))[:2] for a, b in zip(cx[ok][::50], cy[ok][::50])])
    n = egm96_undulation(lonlat[:, 0], lonlat[:, 1])
    assert 45 < n.mean() < 55  # EGM96 in southern France
    np.testing.assert_allclose((ellipsoidal.heights - geoid.heights)[ok][::50], n, atol=1e-6)
    other = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=20.0, k=0, crs="EPSG:2154"))  # Lambert-93
    assert other.srs.GetAuthorityCode(None) == "2154"
    # a point of the cloud lands at its Lambert-93 position
    lx, ly = osr.CoordinateTransformation(srs(UTM31), srs(2154)).TransformPoint(float(x[0]), float(y[0]))[:2]
    assert other.grid.x0 <= lx <= other.grid.x0 + other.grid.cols * 20 and other.grid.x0 % 20 == 0


def test_reads_las_and_geopackage_clouds_with_sigma(tmp_path):
    rng = np.random.default_rng(9)
    lon, lat = 6.0 + rng.uniform(0, 0.02, 500), 44.0 + rng.uniform(0, 0.02, 500)
    h = 300 + rng.uniform(0, 10, 500)
    fields = {"sigma_h": rng.uniform(0.2, 0.9, 500).astype(np.float32)}
    for name in ("c.las", "c.gpkg"):
        path, _, _ = pointcloud.write_point_cloud(tmp_path / name, lon, lat, h, fields)
        points = point_input.read_points(path)
        x, y = utm(lon, lat, 32631 + 1)
        order, truth = np.argsort(points.x), np.argsort(x)
        np.testing.assert_allclose(points.x[order], x[truth], atol=1e-3)
        np.testing.assert_allclose(points.z[order], h[truth], atol=1e-3)
        np.testing.assert_allclose(points.sigma_h[order], fields["sigma_h"][truth], atol=1e-6)
        assert points.srs.GetAuthorityCode(None) == "32632"
    result = tin_dem.interpolate_dem(points, tin_dem.DemParams(cell=50.0, k=0), precision=True)
    ok = np.isfinite(result.heights)
    assert "sigma_h" in result.precision_kind and np.isfinite(result.precision[ok]).all()
    assert 0.2 <= np.nanmin(result.precision) and np.nanmax(result.precision) <= 0.9


def test_precision_is_the_distance_to_the_nearest_point_without_sigma():
    x, y, z = cloud(500, seed=10, size=300.0)
    result = tin_dem.interpolate_dem(
        point_input.PointSet(x, y, z, srs(UTM31)), tin_dem.DemParams(cell=5.0, k=0), precision=True
    )
    cx, cy = result.grid.centres()
    ok = np.isfinite(result.heights)
    d = np.hypot(cx[ok][:, None] - x[None], cy[ok][:, None] - y[None]).min(axis=1)
    np.testing.assert_allclose(result.precision[ok], d, atol=1e-9)
    assert np.isnan(result.precision[~ok]).all() and "distance" in result.precision_kind


def test_written_geotiff_is_tiled_with_overviews_and_nodata(tmp_path):
    x, y, z = cloud(20000, seed=11, size=6000.0)
    result = tin_dem.interpolate_dem(
        point_input.PointSet(x, y, z, srs(UTM31)), tin_dem.DemParams(cell=10.0, k=0), precision=True
    )
    tin_dem.write_dem(result, tmp_path / "dem.tif", tmp_path / "precision.tif")
    ds = gdal.Open(str(tmp_path / "dem.tif"))
    band = ds.GetRasterBand(1)
    assert ds.GetMetadata("IMAGE_STRUCTURE")["COMPRESSION"] == "DEFLATE" and band.GetBlockSize() == [256, 256]
    assert band.GetOverviewCount() == 2 and band.GetNoDataValue() == geotiff.NODATA
    assert ds.GetSpatialRef().GetAuthorityCode(None) == str(UTM31)
    assert ds.GetGeoTransform() == result.grid.geotransform
    data = band.ReadAsArray()
    gap = np.isnan(result.heights)
    assert gap.any() and (data[gap] == geotiff.NODATA).all()
    np.testing.assert_allclose(data[~gap], result.heights[~gap], rtol=1e-7)
    precision = gdal.Open(str(tmp_path / "precision.tif"))
    assert precision.GetRasterBand(1).GetNoDataValue() == geotiff.NODATA


def test_bad_input_and_cancel(tmp_path):
    x, y, z = cloud(100, seed=12)
    utm31 = srs(UTM31)
    for n in (0, 2):
        with pytest.raises(InputError, match="at least 3 points"):
            tin_dem.interpolate_dem(point_input.PointSet(x[:n], y[:n], z[:n], utm31))
    with pytest.raises(InputError, match="one line"):
        tin_dem.interpolate_dem(point_input.PointSet(x[:10], x[:10] * 2, z[:10], utm31))
    with pytest.raises(InputError, match="datum"):
        tin_dem.interpolate_dem(point_input.PointSet(x, y, z, utm31), tin_dem.DemParams(datum="navd88"))
    with pytest.raises(InputError, match="maximum edge"):
        tin_dem.interpolate_dem(point_input.PointSet(x, y, z, utm31), tin_dem.DemParams(max_edge=1.0))
    with pytest.raises(InputError, match="cannot open"):
        point_input.read_points(tmp_path / "missing.gpkg")

    result = tin_dem.interpolate_dem(point_input.PointSet(x, y, z, utm31), tin_dem.DemParams(cell=50.0, k=0))
    with pytest.raises(CancelledError):
        tin_dem.write_dem(result, tmp_path / "dem.tif", feedback=Feedback(cancel_at=40))
    assert not list(tmp_path.iterdir())


def test_default_maximum_edge_follows_the_point_spacing():
    """A 50 m matching lattice with one point missing: the default bridges that hole (edges up to
    2.24 spacings) but not a hole of two; at 10 m cells the spacing rules, at 100 m the 3 cells."""
    from pushbroom.algorithms.surface.tin_dem import default_max_edge

    gx, gy = (v.ravel().astype(float) for v in np.meshgrid(np.arange(20) * 50.0, np.arange(20) * 50.0))
    assert default_max_edge(gx, gy, 10.0) == pytest.approx(125.0)
    assert default_max_edge(gx, gy, 100.0) == pytest.approx(300.0)
    assert 2.24 * 50.0 < default_max_edge(gx, gy, 10.0) < 3.0 * 50.0
