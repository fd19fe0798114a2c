"""The per-cell DEM of dense points against a plain numpy loop over the cells, and through the tiled DEM
step: tiles and executions leave the same rasters, the counts add up, the wrong combinations are clear
errors."""

import numpy as np
import pytest

from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.surface import pointcloud
from pushbroom.algorithms.surface.cell_dem import (
    MEDIAN_SE,
    MIN_SPREAD,
    THREE_RAYS,
    TWO_RAYS,
    UNREFINED,
    CellSettings,
    cells_on_grid,
)
from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
from pushbroom.algorithms.surface.tin_dem import DemParams
from pushbroom.algorithms.surface.tin_grid import Grid
from tests.helpers.dem_cloud import UTM31, read_raster


def dense_points(seed=3, n=20000, outliers=200):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 200.0, n)
    y = rng.uniform(0.0, 150.0, n)
    z = 100.0 + 0.1 * x + np.where(x > 120.0, 15.0, 0.0) + rng.normal(0.0, 0.4, n)  # a 15 m step at x = 120
    z[rng.choice(n, outliers, replace=False)] += rng.uniform(10.0, 40.0, outliers)
    return x, y, z, rng.uniform(0.3, 1.0, n)


def reference(x, y, z, sigma, grid, k, radius=0):
    """Per cell: the median, MAD test, median, count and precision of the module's docstring, by a loop, from
    the points of the nearest ring of cells (up to `radius`) that has some; and the outliers of own cells."""
    out = (
        np.full((grid.rows, grid.cols), np.nan),
        np.zeros((grid.rows, grid.cols)),
        np.full((grid.rows, grid.cols), np.nan),
    )
    col = np.floor((x - grid.x0) / grid.cell).astype(int)
    row = np.floor((grid.y0 - y) / grid.cell).astype(int)
    removed = 0
    for r in range(grid.rows):
        for c in range(grid.cols):
            ring = np.maximum(np.abs(row - r), np.abs(col - c))
            m = (ring == ring.min()) & (ring <= radius)
            if not m.any():
                continue
            zz, ss = z[m], None if sigma is None else sigma[m]
            med = np.median(zz)
            mad = np.median(np.abs(zz - med))
            keep = np.abs(zz - med) <= k * max(1.4826 * mad, MIN_SPREAD)
            removed += int((~keep).sum()) if ring[m][0] == 0 else 0
            zz = zz[keep]
            med = np.median(zz)
            n = len(zz)
            if ss is not None:  # one measurement: the RMS of the points' sigmas
                error = np.sqrt(np.mean(ss[keep] ** 2))
            else:  # independent points: the standard error of their median
                error = MEDIAN_SE * (1.4826 * np.median(np.abs(zz - med)) if n >= 3 else np.nan) / np.sqrt(n)
            out[0][r, c], out[1][r, c], out[2][r, c] = med, n, error
    return out, removed


@pytest.mark.parametrize("with_sigma", [False, True])
def test_cells_against_a_loop(with_sigma):
    x, y, z, sigma = dense_points()
    grid = Grid(0.0, 150.0, 10.0, 20, 15)
    heights, count, precision, removed, ring = cells_on_grid(
        x, y, z, sigma if with_sigma else None, grid, CellSettings(k=3.0)
    )
    (h_ref, n_ref, p_ref), removed_ref = reference(x, y, z, sigma if with_sigma else None, grid, 3.0)
    np.testing.assert_allclose(heights, h_ref, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(count, n_ref)
    np.testing.assert_allclose(precision, p_ref, rtol=1e-5)
    assert removed == removed_ref and removed >= 190  # the outliers, and hardly anything else
    assert (ring == 0).all()
    assert np.nanmax(np.abs(heights[:, :12] - (100.0 + 0.1 * (np.arange(12) * 10 + 5)))) < 1.0


@pytest.mark.parametrize("radius", [1, 2])
def test_empty_cells_take_the_nearest_ring_of_points(radius):
    x, y, z, _ = dense_points(n=900, outliers=30)  # 0.3 points per 2 m cell: most cells empty
    x, y, z = (v[(np.hypot(x - 100.0, y - 75.0) > 12.0)] for v in (x, y, z))  # and a hole of 6 cells
    grid = Grid(0.0, 150.0, 2.0, 100, 75)
    cells = cells_on_grid(x, y, z, None, grid, CellSettings(k=3.0, radius=radius))
    (h_ref, n_ref, p_ref), removed_ref = reference(x, y, z, None, grid, 3.0, radius)
    np.testing.assert_allclose(cells.heights, h_ref, rtol=0, atol=1e-4)
    np.testing.assert_array_equal(cells.counts, n_ref)
    np.testing.assert_allclose(cells.precision, p_ref, rtol=1e-5)
    assert cells.removed == removed_ref
    own = cells_on_grid(x, y, z, None, grid, CellSettings(k=3.0))
    assert (cells.ring == 0).sum() == np.isfinite(own.heights).sum() < 0.3 * grid.rows * grid.cols
    np.testing.assert_array_equal(cells.heights[cells.ring == 0], own.heights[cells.ring == 0])
    assert set(np.unique(cells.ring)) == set(range(radius + 1)) | {255}  # the hole's middle stays a gap
    assert np.isnan(cells.heights[cells.ring == 255]).all() and np.isfinite(cells.heights[cells.ring < 255]).all()


def write(path, x, y, z, sigma=None):
    fields = {} if sigma is None else {"sigma_h": sigma.astype(np.float32)}
    pointcloud.write_las(path, 500000.0 + x, 4800000.0 + y, z, fields, srs(UTM31))
    return path


def test_tiles_and_executions_leave_the_same_rasters(tmp_path):
    x, y, z, sigma = dense_points(n=60000)
    cloud = write(tmp_path / "dense.las", x, y, z, sigma)
    runs = {}
    for name, tile, execution in (
        ("one", 1024, Execution()),
        ("tiles", 16, Execution("threads", 2)),
        ("processes", 16, Execution("processes", 2)),
    ):
        out = tmp_path / f"{name}.tif"
        result = dem_from_point_cloud(
            cloud,
            out,
            DemParams(cell=2.0, method="cells", tile=tile, k=3.0, execution=execution),
            precision_path=tmp_path / f"{name}_p.tif",
            count_path=tmp_path / f"{name}_n.tif",
            mask_path=tmp_path / f"{name}_m.tif",
        )
        runs[name] = [
            read_raster(p)[0]
            for p in (out, tmp_path / f"{name}_p.tif", tmp_path / f"{name}_n.tif", tmp_path / f"{name}_m.tif")
        ]
        assert result.points + result.removed[0] == len(x)
        mask = runs[name][3]
        # the points count once, in their own cells; the few empty cells take their neighbours' (radius 1)
        assert np.nansum(runs[name][2][mask == 0]) == result.points
        assert 0 < (mask == 2).sum() < 0.01 * mask.size and np.isfinite(runs[name][0][mask == 2]).all()
    assert result.tiles == -(-result.grid.cols // 16) * -(-result.grid.rows // 16) > 20
    for name in ("tiles", "processes"):
        for a, b in zip(runs["one"], runs[name]):
            np.testing.assert_array_equal(a, b)


def test_wrong_combinations_are_clear_errors(tmp_path):
    x, y, z, _ = dense_points(n=1000)
    cloud = write(tmp_path / "dense.las", x, y, z)
    with pytest.raises(InputError, match="per-cell method"):
        dem_from_point_cloud(cloud, tmp_path / "a.tif", DemParams(cell=5.0), count_path=tmp_path / "n.tif")
    with pytest.raises(InputError, match="breaklines"):
        dem_from_point_cloud(
            cloud, tmp_path / "b.tif", DemParams(cell=5.0, method="cells"), breaklines=(tmp_path / "lines.gpkg", None)
        )
    with pytest.raises(InputError, match="method"):
        DemParams(method="kriging").check()
    assert not list(tmp_path.glob("*.tif"))


def test_a_cell_uses_its_best_tier_of_points():
    x, y, z, _ = dense_points(outliers=0)
    rng = np.random.default_rng(5)
    tier = np.digitize(rng.uniform(size=x.size), [0.4, 0.7]).astype(np.uint8)  # 40 % three rays, 30 % two
    tier[(x < 50.0) & (y < 50.0) & (tier == THREE_RAYS)] = TWO_RAYS  # a corner without three rays
    tier[(x > 150.0) & (y > 100.0)] = UNREFINED  # and one with no refined point
    z = z + np.array([0.0, 2.0, 5.0])[tier]  # each tier its own offset
    grid = Grid(0.0, 150.0, 10.0, 20, 15)

    def first_finite(*layers):
        out = np.full(layers[0].shape, np.nan, np.float32)
        for layer in layers:
            out = np.where(np.isfinite(out), out, layer)
        return out

    def alone(t, radius=0):
        m = tier == t
        return cells_on_grid(x[m], y[m], z[m], None, grid, CellSettings(k=0.0, radius=radius)).heights

    heights, count, *_ = cells_on_grid(x, y, z, None, grid, CellSettings(k=0.0), tier=tier)
    np.testing.assert_array_equal(heights, first_finite(alone(0), alone(1), alone(2)))
    assert np.isnan(alone(0)[10:, :5]).all() and np.isfinite(alone(1)[10:, :5]).all()
    assert np.isnan(alone(1)[:5, 15:]).all() and np.isfinite(heights[:5, 15:]).all()
    strict = cells_on_grid(x, y, z, None, grid, CellSettings(k=0.0, fallback=False), tier=tier).heights
    np.testing.assert_array_equal(strict, first_finite(alone(0), alone(1)))
    assert np.isnan(strict[:5, 15:]).all()
    # with a radius, a better tier a cell away comes before a cell's own worse one
    near = cells_on_grid(x, y, z, None, grid, CellSettings(k=0.0, radius=1), tier=tier)
    np.testing.assert_array_equal(near.heights, first_finite(alone(0, 1), alone(1, 1), alone(2, 1)))
    assert (near.ring[10, :5] == 1).all() and (near.ring[11:, 4] == 1).all() and (near.ring[11:, :4] == 0).all()


def test_gaps_filled_and_flagged(tmp_path):
    from osgeo import gdal

    x, y, z, _ = dense_points(n=60000, outliers=0)
    strip = (x > 130.0) & (x < 190.0)  # 30 cells wide: its middle beyond reach
    hole = (np.hypot(x - 60.0, y - 75.0) < 15.0) | strip  # and a round hole
    rho = np.where(rng_mask := np.random.default_rng(1).uniform(size=x.size) < 0.3, np.nan, 0.9)
    keep = ~hole | (~np.isfinite(rho) & ~strip)  # the hole has unrefined points only
    fields = {"rho": rho[keep].astype(np.float32)}
    cloud = tmp_path / "dense.las"
    pointcloud.write_las(cloud, 500000.0 + x[keep], 4800000.0 + y[keep], z[keep], fields, srs(UTM31))
    plain = dem_from_point_cloud(cloud, tmp_path / "plain.tif", DemParams(cell=2.0, method="cells", k=0.0))
    result = dem_from_point_cloud(
        cloud, tmp_path / "dem.tif", DemParams(cell=2.0, method="cells", k=0.0, fallback=False, fill=10.0, tile=32)
    )
    assert rng_mask.any() and plain.mask_path is None and result.mask_path == str(tmp_path / "dem_filled.tif")
    dem, _, _ = read_raster(tmp_path / "dem.tif")
    before, _, _ = read_raster(tmp_path / "plain.tif")
    mask = gdal.Open(result.mask_path).ReadAsArray()
    # the round hole (no refined point) is filled and flagged; the measured cells are the refined medians
    assert result.filled == (mask == 1).sum() > 80
    assert np.isfinite(dem[mask == 1]).all() and (mask[np.isfinite(before) & ~np.isfinite(dem)] == 255).all()
    gx, gy = result.grid.centres()
    in_hole = np.hypot(gx - 500060.0, gy - 4800075.0) < 11.0  # its cells more than a cell (radius 1) inside
    assert (mask[in_hole] == 1).all() and np.abs(dem[in_hole] - (100.0 + 0.1 * (gx[in_hole] - 500000.0))).max() < 1.5
    # the middle of the strip lies beyond 10 cells of any measured cell: still a gap, flagged 255; and the strip,
    # 30 cells wide, is no gap the measured cells enclose (their closing by 21 cells): none of it is filled
    middle = np.abs(gx - 500160.0) < 8.0
    assert (mask[middle] == 255).all() and np.isnan(dem[middle]).all()
    in_strip = np.abs(gx - 500160.0) < 28.0
    assert not (mask[in_strip] == 1).any() and (mask[in_strip] == 255).mean() > 0.9
    assert ((mask != 255) == np.isfinite(dem)).all() and (mask == 2).sum() > 50  # the holes' rims: radius 1
    with pytest.raises(InputError, match="gap filling is for the per-cell DEM"):
        dem_from_point_cloud(cloud, tmp_path / "tin.tif", DemParams(cell=2.0, fill=5.0))


@pytest.mark.parametrize("two_ray_sigma", [0.3, 0.5, 0.8])
def test_a_cell_takes_its_own_points_where_they_are_no_less_precise_than_the_rings(two_ray_sigma):
    """The precision rule (cell_dem's docstring): the corner without three-ray points, whose border cells take
    three-ray points (sigma_h 0.5 m) a cell away, takes its own two-ray points instead where theirs is no worse."""
    x, y, z, _ = dense_points(outliers=0)
    rng = np.random.default_rng(5)
    tier = np.digitize(rng.uniform(size=x.size), [0.4, 0.7]).astype(np.uint8)
    tier[(x < 50.0) & (y < 50.0) & (tier == THREE_RAYS)] = TWO_RAYS
    z = z + np.array([0.0, 2.0, 5.0])[tier]
    sigma = np.where(tier == TWO_RAYS, two_ray_sigma, 0.5)
    grid = Grid(0.0, 150.0, 10.0, 20, 15)
    settings = CellSettings(k=0.0, radius=1)
    tiers_first = cells_on_grid(x, y, z, None, grid, settings, tier=tier)
    border = tiers_first.ring == 1  # the corner's cells beside three-ray ones
    assert border.sum() == 9
    cells = cells_on_grid(x, y, z, sigma, grid, settings, tier=tier)
    m = tier == TWO_RAYS
    own_two = cells_on_grid(x[m], y[m], z[m], sigma[m], grid, CellSettings(k=0.0))
    if two_ray_sigma <= 0.5:  # no worse: the cell's own
        assert (cells.ring[border] == 0).all()
        np.testing.assert_array_equal(cells.heights[border], own_two.heights[border])
        np.testing.assert_array_equal(cells.counts[border], own_two.counts[border])
        np.testing.assert_allclose(cells.precision[border], two_ray_sigma, rtol=1e-6)
    else:
        assert (cells.ring[border] == 1).all()
        np.testing.assert_array_equal(cells.heights[border], tiers_first.heights[border])
    np.testing.assert_array_equal(cells.heights[~border], tiers_first.heights[~border])
    assert cells.removed == tiers_first.removed == 0


def test_the_precision_rule_never_takes_unrefined_points_nor_mixed_sigmas_and_counts_its_outliers():
    """The rule takes a cell's own refined points only (with FALLBACK on, a cell whose own points are unrefined keeps
    the ring's refined ones, however small their a priori sigma); one point without sigma_h turns the sigmas off for
    the whole grid (the tier alone, the MAD's precision); the outliers the taken cells drop are counted."""
    x, y, z, _ = dense_points(outliers=0)
    rng = np.random.default_rng(5)
    tier = np.digitize(rng.uniform(size=x.size), [0.4, 0.7]).astype(np.uint8)
    corner = (x < 50.0) & (y < 50.0)
    tier[corner] = np.where(tier[corner] == THREE_RAYS, TWO_RAYS, tier[corner])
    z = z + np.array([0.0, 2.0, 5.0])[tier]
    grid = Grid(0.0, 150.0, 10.0, 20, 15)
    settings = CellSettings(k=0.0, radius=1)
    border = cells_on_grid(x, y, z, None, grid, settings, tier=tier).ring == 1
    # the corner's refined points unrefined: own unrefined points of a tiny sigma against the ring's refined ones
    unrefined = np.where(corner & (tier == TWO_RAYS), UNREFINED, tier).astype(np.uint8)
    sigma = np.where(unrefined == UNREFINED, 0.01, 0.5)
    fallback = cells_on_grid(x, y, z, sigma, grid, settings, tier=unrefined)
    plain = cells_on_grid(x, y, z, None, grid, settings, tier=unrefined)
    assert (fallback.ring[border] == 1).all()
    np.testing.assert_array_equal(fallback.heights, plain.heights)
    # one point without sigma_h: no rule, and the precision of every cell the MAD's
    sigma = np.where(tier == TWO_RAYS, 0.3, 0.5)
    sigma[np.flatnonzero(tier == THREE_RAYS)[0]] = np.nan
    mixed = cells_on_grid(x, y, z, sigma, grid, settings, tier=tier)
    unknown = cells_on_grid(x, y, z, None, grid, settings, tier=tier)
    np.testing.assert_array_equal(mixed.heights, unknown.heights)
    np.testing.assert_array_equal(mixed.precision, unknown.precision)
    # outliers among the taken cells' own points: counted once
    z2 = z.copy()
    hits = np.flatnonzero(corner & (tier == TWO_RAYS))[:40]
    z2[hits] += 30.0
    sigma = np.where(tier == TWO_RAYS, 0.3, 0.5)
    strict = CellSettings(k=3.0, radius=1)
    cells = cells_on_grid(x, y, z2, sigma, grid, strict, tier=tier)
    assert (cells.ring[border] == 0).all()
    tiers_first = cells_on_grid(x, y, z2, None, grid, strict, tier=tier)
    col, row = np.floor(x / 10.0).astype(int), np.floor((150.0 - y) / 10.0).astype(int)
    in_border = border[row.clip(0, 14), col.clip(0, 19)] & (tier == TWO_RAYS)
    alone = cells_on_grid(x[in_border], y[in_border], z2[in_border], None, grid, CellSettings(k=3.0))
    assert alone.removed > 0
    assert cells.removed == tiers_first.removed + alone.removed
