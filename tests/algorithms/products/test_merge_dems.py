"""products.merge_dems on DEMs of an analytic terrain (ground truth by construction): the inverse-variance mean and
its standard error, the count, the outliers left out, the co-registration of a shifted DEM, no seam at a DEM's edge,
another cell size resampled and said, DEMs that do not overlap refused, the result independent of the execution."""

import numpy as np
import pytest

from pushbroom.algorithms import crs
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.products import merge_dems as merge
from pushbroom.algorithms.surface.geotiff import write_float_raster
from tests.helpers.dem_cloud import read_raster
from tests.helpers.dem_shift import CELL, ORIGIN, UTM, centres, terrain
from tests.helpers.feedback import Feedback


def raster(folder, name, values, col0, row0, cell=CELL, shift=(0.0, 0.0)):
    """A raster of `values` whose corner is cell (col0, row0) of the lattice at ORIGIN, its grid moved by `shift`."""
    gt = (ORIGIN[0] + col0 * CELL - shift[0], cell, 0, ORIGIN[1] - row0 * CELL - shift[1], 0, -cell)
    return str(write_float_raster(str(folder / name), values, gt, crs.srs(UTM)))


def surface(col0, row0, cols, rows, cell=CELL):
    """The terrain at the centres of the cells from cell (col0, row0) of the lattice at ORIGIN on."""
    return terrain(*centres((ORIGIN[0] + col0 * CELL, ORIGIN[1] - row0 * CELL), cols, cell, rows))


@pytest.fixture(scope="module")
def dems(tmp_path_factory):
    """A: 200 x 200 cells, noise 0.3 m; B: 200 x 200 cells from column 100 on, noise 0.6 m, 0.8 m higher and its grid
    moved 6 m east; each with its precision raster."""
    folder = tmp_path_factory.mktemp("merge")
    rng = np.random.default_rng(5)
    a = surface(0, 0, 200, 200) + rng.normal(0, 0.3, (200, 200))
    b = surface(100, 0, 200, 200) + 0.8 + rng.normal(0, 0.6, (200, 200))
    return {
        "folder": folder,
        "a": raster(folder, "a.tif", a, 0, 0),
        "b": raster(folder, "b.tif", b, 100, 0, shift=(-6.0, 0.0)),
        "sa": raster(folder, "sa.tif", np.full((200, 200), 0.3), 0, 0),
        "sb": raster(folder, "sb.tif", np.full((200, 200), 0.6), 100, 0, shift=(-6.0, 0.0)),
    }


def read(path):
    """(values with NaN nodata, geotransform) of band 1 of `path`."""
    return read_raster(path)[:2]


def run(dems, tmp_path, **settings):
    outputs = merge.MergeOutputs(str(tmp_path / "m.tif"), str(tmp_path / "se.tif"), str(tmp_path / "n.tif"))
    params = merge.MergeParams((dems["a"], dems["b"]), (dems["sa"], dems["sb"]), **settings)
    return merge.merge_dems(params, outputs), outputs


def test_coregistered_inverse_variance_mean_without_a_seam(dems, tmp_path):
    result, out = run(dems, tmp_path)
    b_shift = result.shifts[1].shift
    assert result.shifts[0] is None and abs(b_shift.east + 6.0) < 0.2 and abs(b_shift.up + 0.8) < 0.05
    h, gt = read(out.dem)
    se, _ = read(out.precision)
    n, _ = read(out.count)
    assert gt[:2] == (ORIGIN[0], CELL) and h.shape == (200, 300)
    truth = surface(0, 0, 300, 200)
    both = n == 2
    assert both[:, 110:190].all() and (n[:, :95] == 1).all() and (n[:, 215:] == 1).all()
    # away from B's edges: the inverse-variance mean, its error 0.3 0.6 / sqrt(0.3^2 + 0.6^2) = 0.268 m
    interior = both & (np.arange(300) > 115)[None, :] & (np.arange(300) < 185)[None, :]
    interior[:15], interior[-15:] = False, False
    assert np.allclose(se[interior], 0.3 * 0.6 / np.hypot(0.3, 0.6), rtol=1e-3)
    err = (h - truth)[interior]
    assert abs(err.mean()) < 0.02 and abs(err.std() - 0.268) < 0.02
    # no seam: the step between neighbouring cells across B's western edge (column 100) is the interior's
    steps = np.abs(np.diff(h - truth, axis=1))
    across, inside = steps[20:180, 98:103].mean(), steps[20:180, 130:170].mean()
    assert across < 1.15 * inside, (across, inside)


def test_outliers_left_out_and_other_cells_said(dems, tmp_path):
    """A third DEM at 20 m cells (resampled, and said) with a 30 m blunder over a block where all three overlap: left
    out there, counted (B is not co-registered here: its 6 m shift costs up to 3 m)."""
    folder = dems["folder"]
    c = surface(0, 0, 100, 100, cell=20.0) + np.random.default_rng(7).normal(0, 0.3, (100, 100))
    c[40:50, 60:70] += 30.0  # where A, B and C overlap
    third = raster(folder, "c.tif", c, 0, 0, cell=20.0)
    sc = raster(folder, "sc.tif", np.full((100, 100), 0.3), 0, 0, cell=20.0)
    outputs = merge.MergeOutputs(str(tmp_path / "m3.tif"), count=str(tmp_path / "n3.tif"))
    params = merge.MergeParams((dems["a"], dems["b"], third), (dems["sa"], dems["sb"], sc), coregister=False)
    log = Feedback()
    result = merge.merge_dems(params, outputs, log)
    h, _ = read(outputs.dem)
    n, _ = read(outputs.count)
    h, n = h[:, :300], n[:, :300]  # B, not co-registered here, reaches 6 m further east
    blunder = np.zeros(h.shape, bool)
    blunder[82:98, 122:138] = True  # inside the 20 m block, clear of its resampled edge
    assert (n[blunder] == 2).all() and np.nanmax(np.abs(h - surface(0, 0, 300, 200))[blunder]) < 3.0
    assert result.outliers >= blunder.sum()
    assert any("c.tif has cells of 20 m: resampled onto the merge's 10 m cells (bilinear)" in m for m in log.messages)


def test_the_execution_does_not_change_the_merge(dems, tmp_path, monkeypatch):
    monkeypatch.setattr(merge, "TILE", 64)  # 4 x 5 tiles, each with its margin
    _, threads = run(dems, tmp_path / "t", coregister=False)
    _, processes = run(dems, tmp_path / "p", coregister=False, execution=Execution("processes", 2))
    monkeypatch.setattr(merge, "TILE", 1024)
    _, whole = run(dems, tmp_path / "w", coregister=False)
    for a, b in ((threads, processes), (threads, whole)):
        for path_a, path_b in zip((a.dem, a.precision, a.count), (b.dem, b.precision, b.count)):
            np.testing.assert_array_equal(read(path_a)[0], read(path_b)[0])


def test_dems_that_do_not_overlap_are_refused(dems, tmp_path):
    far = raster(dems["folder"], "far.tif", surface(2000, 0, 50, 50), 2000, 0)
    with pytest.raises(InputError, match="cannot be co-registered to .*a.tif.*does not overlap"):
        merge.merge_dems(merge.MergeParams((dems["a"], far)), merge.MergeOutputs(str(tmp_path / "x.tif")))
    with pytest.raises(InputError, match="one precision raster per DEM"):
        merge.merge_dems(
            merge.MergeParams((dems["a"], far), (dems["sa"],)), merge.MergeOutputs(str(tmp_path / "x.tif"))
        )
    with pytest.raises(InputError, match="two DEMs or more"):
        merge.merge_dems(merge.MergeParams((dems["a"],)), merge.MergeOutputs(str(tmp_path / "x.tif")))
    assert not (tmp_path / "x.tif").exists()


def test_the_median_of_the_heights_is_numpys():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(5, 40, 40))
    values[rng.random(values.shape) < 0.4] = np.nan
    n = np.isfinite(values).sum(axis=0)
    got = merge._median(values, n)
    with np.errstate(all="ignore"), pytest.warns(RuntimeWarning):  # numpy's own warns on the empty cells
        expected = np.nanmedian(values, axis=0)
    assert (n == 0).any() and np.isnan(got[n == 0]).all()
    np.testing.assert_allclose(got[n > 0], expected[n > 0])


def test_another_crs_takes_its_own_units_and_pairs_are_checked(dems, tmp_path):
    """An output CRS in degrees: the cells are the first DEM's as warped there (about 1e-4 degree), not its 10 (m)
    read as degrees; given a CELL, that one. A precision raster off its DEM's grid is refused."""
    out = merge.MergeOutputs(str(tmp_path / "ll.tif"))
    merge.merge_dems(merge.MergeParams((dems["a"], dems["b"]), coregister=False, crs="EPSG:4326"), out)
    gt = read(out.dem)[1]
    assert 5e-5 < gt[1] < 3e-4 and read(out.dem)[0].shape[1] < 1000
    out = merge.MergeOutputs(str(tmp_path / "ll2.tif"))
    merge.merge_dems(merge.MergeParams((dems["a"], dems["b"]), coregister=False, crs="EPSG:4326", cell=5e-4), out)
    assert read(out.dem)[1][1] == 5e-4
    with pytest.raises(InputError, match="does not lie on the grid of the DEM"):
        merge.merge_dems(
            merge.MergeParams((dems["a"], dems["b"]), (dems["sb"], dems["sa"])),
            merge.MergeOutputs(str(tmp_path / "x.tif")),
        )
