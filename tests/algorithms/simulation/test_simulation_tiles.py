"""The simulator tile by tile and beyond its source DEM: a scene made in many ground tiles equals
the scene made in one, grids kept in files equal grids kept in memory, the extended DEM keeps the
source and continues it, and a full-size SPOT 5 scene (60 km) is planned inside it."""

import os

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms.crs import egm96_undulation
from pushbroom.algorithms.disk_array import DiskArray
from pushbroom.algorithms.simulation import SceneConfig, scene, simulate_scene, terrain
from pushbroom.algorithms.simulation.grid import Grid
from pushbroom.algorithms.simulation.tiles import value_range

gdal.UseExceptions()


@pytest.fixture(scope="module")
def source():
    return terrain.jacksboro_dem()


def _read(path):
    return gdal.Open(str(path)).ReadAsArray()


@pytest.mark.slow
def test_ground_tiles_do_not_change_the_scene(tmp_path):
    """One ground tile against 5 x 5 tiles of 96 cells (markers crossing tile borders): the same
    DSM, DTM, land cover and points. The radiance differs only where a shadow ray grazes an edge
    (its coordinates, counted from the window's origin, round differently: a cell or so), the
    images by 1 DN where the PSF filter's FFT of each tile rounds differently from the whole
    grid's (a DN rounding flip), a few DN around a grazing shadow."""
    config = SceneConfig.small(size_km=1.5, points=6, markers=True)
    whole = simulate_scene(config, tmp_path / "whole")
    tiled = simulate_scene(config, tmp_path / "tiled", tile=96)
    assert _read(whole["dsm"]).shape[0] > 4 * 96
    for name in ("dsm", "dtm", "classes"):
        assert np.array_equal(_read(whole[name]), _read(tiled[name])), name
    with open(whole["points"]) as a, open(tiled["points"]) as b:
        assert a.read() == b.read()
    ortho = _read(whole["orthoimage"]) != _read(tiled["orthoimage"])
    print(f"orthoimage: {ortho.sum()} of {ortho.size} cells differ")
    assert ortho.mean() < 1e-4
    for name, product in whole["images"].items():
        d = np.abs(_read(product["imagery"]).astype(int) - _read(tiled["images"][name]["imagery"]).astype(int))
        print(
            f"{name}: {100 * np.mean(d > 0):.3f} % of the pixels differ, {np.sum(d > 1)} by more than 1 DN "
            f"(at most {d.max()} DN)"
        )
        assert np.mean(d > 0) < 0.01 and np.mean(d > 1) < 1e-4 and d.max() <= 10
    assert sorted(os.listdir(tiled["folder"])) == sorted(os.listdir(whole["folder"]))  # no work files left


def test_terrain_in_files_and_tiles_equals_terrain_in_memory(tmp_path, source):
    lon_min, lat_min, lon_max, lat_max = source.bounds
    grid = Grid.covering((lon_min + 0.05, lat_min + 0.05, lon_max - 0.05, lat_max - 0.05), 40.0)
    memory = terrain.build_terrain(source, grid, seed=5)
    files = terrain.build_terrain(source, grid, seed=5, folder=str(tmp_path), tile=64)
    assert isinstance(files.dsm, DiskArray) and grid.rows > 2 * 64
    np.testing.assert_array_equal(files.towns, memory.towns)
    for name in ("classes", "feature"):
        assert np.array_equal(getattr(files, name)[:, :], getattr(memory, name)), name
    for name in ("dtm", "dsm"):
        np.testing.assert_allclose(getattr(files, name)[:, :], getattr(memory, name), rtol=0, atol=1e-9)
    whole = files.dsm[:, :]
    assert value_range(files.dsm, grid.shape, 64) == (whole.min(), whole.max())


def test_disk_array_reads_and_writes_slices(tmp_path):
    a = DiskArray(str(tmp_path / "a.npy"), (5, 7), np.float32)
    a[1:3, 2:6] = np.arange(8).reshape(2, 4)
    a[np.array([4]), np.array([0])] = 9
    want = np.zeros((5, 7), np.float32)
    want[1:3, 2:6] = np.arange(8).reshape(2, 4)
    want[4, 0] = 9
    assert np.array_equal(a[:, :], want) and a[2, 5] == 7
    assert np.array_equal(np.load(tmp_path / "a.npy"), want)


def test_extended_dem_keeps_the_source_and_continues_it(source):
    ext = terrain.extended_dem(source)
    r, c = source.heights.shape
    assert ext.heights.shape == (3 * r, 3 * c)
    assert np.array_equal(ext.heights[r : 2 * r, c : 2 * c], source.heights)
    assert np.array_equal(ext.lake[r : 2 * r, c : 2 * c], source.lake)
    np.testing.assert_allclose(ext.geoid[r : 2 * r, c : 2 * c], source.geoid, atol=1e-9)
    assert ext.planning_range == source.planning_range
    # continuous across the mirror lines: a jump of at most the continuation's first half cell
    jumps = np.concatenate(
        [
            ext.heights[r - 1, c : 2 * c] - ext.heights[r, c : 2 * c],
            ext.heights[2 * r, c : 2 * c] - ext.heights[2 * r - 1, c : 2 * c],
            ext.heights[r : 2 * r, c - 1] - ext.heights[r : 2 * r, c],
            ext.heights[r : 2 * r, 2 * c] - ext.heights[r : 2 * r, 2 * c - 1],
        ]
    )
    assert np.abs(jumps).max() < 1.0
    # far from the source the copies are not plain mirrors (the fine detail, land cover and objects of a scene
    # differ anyway: they are procedural in the scene's coordinates)
    mirrored = np.pad(source.heights, ((r, r), (c, c)), mode="symmetric")
    far = (ext.heights - mirrored)[: r // 2, : c // 2]
    rms = float(np.sqrt(np.mean(far**2)))
    print(f"continuation far from the source: RMS {rms:.1f} m, max {np.abs(far).max():.1f} m")
    assert 3.0 < rms and np.abs(far).max() <= terrain.CONTINUATION_AMPLITUDE
    # the geoid is PROJ's EGM96 at the cells' own positions, not mirrored
    lon0, dlon, _, lat0, _, dlat = ext.geotransform
    ii, jj = np.array([0, 5, 3 * r - 1]), np.array([3 * c - 1, 7, 0])
    np.testing.assert_allclose(
        ext.geoid[ii, jj], egm96_undulation(lon0 + (jj + 0.5) * dlon, lat0 + (ii + 0.5) * dlat), atol=1e-9
    )


def test_a_full_spot5_scene_is_planned_inside_the_extended_dem(source):
    """60 km: HRG 12 000 x 12 000 px, HRS 6 000 detectors of 10 m; about 14 700^2 ground cells,
    which is why the grids are tiled."""
    config = SceneConfig(size_km=60.0).resolved()
    images, grid, _ = scene._plan(config, terrain.extended_dem(source))
    sizes = {image.name: (image.ncols, image.nrows) for image in images}
    assert sizes["HRG"][0] == 12000 and abs(sizes["HRG"][1] - 12000) < 200
    assert sizes["HRS1"][0] == 6000 and sizes["HRS2"][0] == 6000
    assert grid.rows * grid.cols > 2e8
    with pytest.raises(Exception, match="source DEM"):
        scene._plan(config, source)
