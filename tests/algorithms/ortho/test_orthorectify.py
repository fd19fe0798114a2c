"""Orthorectification (algorithms/ortho) on the small simulated SPOT 5 scene: the HRG image with its
truth model on the true DSM against the simulator's true orthoimage (geometry by least-squares matching),
the coarse-grid bound against the exact per-cell chain, the RPC path, DEMs in another CRS and in EGM96,
nodata, occlusions against the model's own ray casting, the resampling kernels against plain numpy."""

import numpy as np
import pytest
from osgeo import gdal
from scipy import ndimage

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import egm96_undulation, srs
from pushbroom.algorithms.dem import Dem, dem_window
from pushbroom.algorithms.dem_store import read_dem, store_dem
from pushbroom.algorithms.errors import CancelledError, InputError
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.ortho import OrthoOutputs, OrthoSettings, OutputGrid, default_grid, orthorectify
from pushbroom.algorithms.ortho.mapping import START_STEP, TileMapper
from pushbroom.algorithms.ortho.occlusion import occluded, ray_direction
from pushbroom.algorithms.ortho.orthorectify import _footprint, _reach
from pushbroom.algorithms.ortho.resampling import BICUBIC, BILINEAR, resample_kernel
from pushbroom.algorithms.sensors.rpc_fit import fit_rpc
from pushbroom.algorithms.simulation.terrain import CITY, FOREST
from tests.helpers.feedback import Feedback
from tests.helpers.ortho_oracle import geometric_error


@pytest.fixture(scope="module")
def scene(small_scene):
    truth = gdal.Open(small_scene["orthoimage"])
    return {
        "paths": small_scene,
        "dsm": read_dem(small_scene["dsm"]),
        "hrg": sensors.load(small_scene["truth_metadata"]["HRG"]),
        "image": small_scene["images"]["HRG"]["imagery"],
        # the true orthoimage's own grid (EPSG:4326, 5 m cells)
        "grid": OutputGrid(srs(4326), truth.GetGeoTransform(), truth.RasterXSize, truth.RasterYSize),
    }


@pytest.mark.parametrize("method", ["bilinear", "bicubic"])
@pytest.mark.ratchet
def test_hrg_on_the_true_dsm_matches_the_true_orthoimage(scene, tmp_path, method, figures):
    out = tmp_path / "hrg.tif"
    result = orthorectify(
        scene["image"],
        scene["hrg"],
        scene["dsm"],
        out,
        grid=scene["grid"],
        settings=OrthoSettings(resampling_method=method),
    )
    shifts = geometric_error(scene["paths"], str(out))
    rms = float(np.sqrt(np.mean(np.sum(shifts**2, axis=1))))
    mean = shifts.mean(axis=0)
    figures.report("patches in the open classes", len(shifts))
    figures.report("shift against the true orthoimage, RMS", rms, "px")
    figures.report("shift against the true orthoimage, mean", mean, "px")
    figures.report("orthoimage", result.summary())
    assert len(shifts) >= 150
    assert rms < 0.25 and np.all(np.abs(mean) < 0.05)
    assert result.bound <= 0.01


def test_the_coarse_grid_bound_holds_against_the_exact_chain(scene, figures):
    grid = default_grid(scene["hrg"], scene["dsm"])
    assert grid.srs.GetAuthorityCode(None) == "32616"
    for max_error, start in ((0.01, 16), (1e-4, 64), (2e-5, 128)):
        mapper = TileMapper(scene["hrg"], scene["dsm"], grid, max_error=max_error, start_step=start)
        tile = mapper.tile(100, 200, 300, 256)
        exact = mapper.exact(100, 200, 300, 256)
        error = np.hypot(tile.col - exact.col, tile.row - exact.row)
        figures.table(
            f"bound {max_error:g} px from step {start}",
            [{"step": tile.step, "achieved bound px": tile.bound, "largest true error px": np.nanmax(error)}],
        )
        assert np.array_equal(np.isnan(tile.col), np.isnan(exact.col))
        assert tile.bound <= max_error and np.nanmax(error) <= tile.bound
    assert tile.step < 128  # the tight bound forced a refinement


def test_rpc_and_rigorous_orthoimages_agree(scene, tmp_path, figures):
    rpc, report = fit_rpc(scene["hrg"], (scene["dsm"].height_range[0] - 100, scene["dsm"].height_range[1] + 100))
    grid = scene["grid"]
    rigorous = TileMapper(scene["hrg"], scene["dsm"], grid).tile(0, 0, grid.rows, grid.cols)
    rational = TileMapper(rpc, scene["dsm"], grid).tile(0, 0, grid.rows, grid.cols)
    cols, rows = scene["hrg"].size
    inside = (rigorous.col >= 0) & (rigorous.col <= cols) & (rigorous.row >= 0) & (rigorous.row <= rows)
    diff = np.hypot(rigorous.col - rational.col, rigorous.row - rational.row)[inside]
    figures.report("RPC vs rigorous image points per cell in the image, max", np.nanmax(diff), "px")
    figures.report("RPC fit", report.summary())
    assert np.nanmax(diff) < report.max_error + 0.02
    orthorectify(scene["image"], rpc, scene["dsm"], tmp_path / "rpc.tif", grid=grid)
    shifts = geometric_error(scene["paths"], str(tmp_path / "rpc.tif"))
    assert np.sqrt(np.mean(np.sum(shifts**2, axis=1))) < 0.25


def test_a_dem_in_another_crs_and_in_egm96_heights(scene, tmp_path, figures):
    utm_dem = tmp_path / "dsm_utm.tif"
    gdal.Warp(str(utm_dem), scene["paths"]["dsm"], dstSRS="EPSG:32616", xRes=5.0, yRes=5.0, resampleAlg="bilinear")
    warped = store_dem(utm_dem, tmp_path).whole()
    assert warped.geotransform != scene["dsm"].geotransform
    grid = default_grid(scene["hrg"], scene["dsm"])
    a = TileMapper(scene["hrg"], scene["dsm"], grid).tile(150, 150, 256, 256)
    b = TileMapper(scene["hrg"], warped, grid).tile(150, 150, 256, 256)
    dh = np.abs(a.h - b.h)
    figures.report("DEM warped to UTM and back, median |dh|", np.nanmedian(dh), "m")
    figures.report("median image-point change", np.nanmedian(np.hypot(a.col - b.col, a.row - b.row)), "px")
    assert np.nanmedian(dh) < 0.5  # two bilinear resamplings of a 5 m DSM with 1-4 m texture
    # the same DSM as EGM96 orthometric heights H = h - N, converted back by store_dem
    ds = gdal.Open(scene["paths"]["dsm"])
    heights = ds.ReadAsArray().astype(np.float64)
    lon0, dlon, _, lat0, _, dlat = ds.GetGeoTransform()
    lon, lat = np.meshgrid(
        lon0 + (np.arange(ds.RasterXSize) + 0.5) * dlon, lat0 + (np.arange(ds.RasterYSize) + 0.5) * dlat
    )
    orthometric = heights - egm96_undulation(lon, lat)
    geoid_dem = tmp_path / "dsm_egm96.tif"
    out = gdal.GetDriverByName("GTiff").Create(str(geoid_dem), ds.RasterXSize, ds.RasterYSize, 1, gdal.GDT_Float64)
    out.SetGeoTransform(ds.GetGeoTransform())
    out.SetProjection(ds.GetProjection())
    out.WriteArray(orthometric)
    out = None
    back = store_dem(geoid_dem, tmp_path, vertical="egm96").whole()
    assert np.abs(back.heights - heights).max() < 0.005
    with pytest.raises(InputError, match="egm96"):
        store_dem(geoid_dem, tmp_path, vertical="navd88")


def test_nodata_outside_the_image_and_the_data_type(scene, tmp_path, figures):
    grid = default_grid(scene["hrg"], scene["dsm"])
    out = tmp_path / "hrg_utm.tif"
    orthorectify(scene["image"], scene["hrg"], scene["dsm"], out, grid=grid)
    ds = gdal.Open(str(out))
    band = ds.GetRasterBand(1)
    assert band.DataType == gdal.GDT_Byte and band.GetNoDataValue() == 0
    assert band.GetOverviewCount() >= 1
    assert ds.GetMetadata("IMAGE_STRUCTURE").get("COMPRESSION") == "DEFLATE"
    assert band.GetBlockSize() == [256, 256]
    values = band.ReadAsArray()
    exact = TileMapper(scene["hrg"], scene["dsm"], grid).exact(0, 0, grid.rows, grid.cols)
    cols, rows = scene["hrg"].size
    outside = ~((exact.col >= 0) & (exact.col <= cols) & (exact.row >= 0) & (exact.row <= rows))
    inside = (exact.col > 1) & (exact.col < cols - 1) & (exact.row > 1) & (exact.row < rows - 1)
    figures.report("cells outside the image", outside.sum())
    figures.report("cells well inside", inside.sum())
    assert outside.sum() > 1000 and inside.sum() > 100000
    assert np.all(values[outside] == 0) and np.all(values[inside] > 0)


def test_occlusions_agree_with_the_models_ray_casting(scene, figures):
    """HRS1 looks 20 degrees forward: cells behind trees and buildings are occluded. Reference: the first
    DSM crossing of the cell's image ray (SpotModel.image_to_dem) lies elsewhere than the cell."""
    model = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    dsm = scene["dsm"]
    grid = default_grid(model, dsm)
    tile = TileMapper(model, dsm, grid).tile(100, 100, 400, 400)
    centre = np.ravel_multi_index((200, 200), tile.col.shape)
    mask = occluded(
        dsm,
        tile.lon,
        tile.lat,
        tile.h,
        ray_direction(model, tile.col.flat[centre], tile.row.flat[centre], *dsm.height_range),
    )
    rng = np.random.default_rng(5)
    pick = rng.choice(np.flatnonzero(np.isfinite(tile.col.ravel())), 12000, replace=False)
    lon, lat, _ = model.image_to_dem(tile.col.ravel()[pick], tile.row.ravel()[pick], dsm)
    me, mn = metres_per_degree(lat)
    distance = np.hypot((lon - tile.lon.ravel()[pick]) * me, (lat - tile.lat.ravel()[pick]) * mn)
    reference = distance > 2.0
    ours = mask.ravel()[pick]
    agree, found, right = np.mean(ours == reference), np.mean(ours[reference]), np.mean(reference[ours])
    figures.report("HRS1 cells occluded", 100 * mask.mean(), "%")
    figures.report("sample occluded by ray casting", 100 * reference.mean(), "%")
    figures.report("agreement", 100 * agree, "%")
    figures.report("occluded found", 100 * found, "%")
    figures.report("flagged right", 100 * right, "%")
    assert reference.sum() > 50 and agree > 0.99 and found > 0.85 and right > 0.85


def test_a_tiles_dem_window_holds_its_occluders(scene):
    """The DEM window a tile task takes (its footprint widened by the rays' reach) gives the whole DEM's
    heights and occlusions for the tile's cells."""
    model = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    dsm = scene["dsm"]
    grid = default_grid(model, dsm)
    window = (100, 100, 250, 250)  # the coarse lattice reaches 6 cells beyond
    tile = TileMapper(model, dsm, grid).tile(*window)
    part = dem_window(
        dsm.heights, dsm.geotransform, dsm.height_range, _footprint(grid, window, _reach(model, dsm), START_STEP)
    )
    assert part.heights.size < dsm.heights.size / 4 and part.height_range == dsm.height_range
    np.testing.assert_allclose(part.height(tile.lon, tile.lat), tile.h, atol=1e-9)
    windowed = TileMapper(model, part, grid).tile(*window)  # the same coarse lattice and bound
    assert (windowed.step, windowed.bound) == pytest.approx((tile.step, tile.bound), rel=1e-6)
    np.testing.assert_allclose(windowed.col, tile.col, atol=1e-6)
    direction = ray_direction(
        model, tile.col.flat[tile.col.size // 2], tile.row.flat[tile.col.size // 2], *dsm.height_range
    )
    whole = occluded(dsm, tile.lon, tile.lat, tile.h, direction)
    assert whole.sum() > 100  # occluded cells to check
    assert np.mean(occluded(part, tile.lon, tile.lat, tile.h, direction) == whole) > 0.9999


def _read(path):
    return gdal.Open(str(path)).ReadAsArray().astype(np.float64)


def test_true_orthoimage_flags_what_the_surface_hides(scene, tmp_path, figures):
    """HRS1 (20 degrees forward) on the true DSM: a true orthoimage. Its occlusion mask flags exactly the cells
    that OCCLUSION makes nodata, and those cells show the occluder: against the simulator's ground radiance (the
    true orthoimage, after a linear radiometric fit on the seen cells) they depart far more than the seen ones.
    On the DTM instead, the roofs and the canopy are displaced (LSM shifts against the true orthoimage)."""
    model = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    image = scene["paths"]["images"]["HRS1"]["imagery"]
    flagged = orthorectify(
        image, model, scene["dsm"], OrthoOutputs(tmp_path / "dsm.tif", tmp_path / "mask.tif"), grid=scene["grid"]
    )
    hidden = orthorectify(
        image,
        model,
        scene["dsm"],
        tmp_path / "hidden.tif",
        grid=scene["grid"],
        settings=OrthoSettings(occluded_nodata=True),
    )
    orthorectify(image, model, read_dem(scene["paths"]["dtm"]), tmp_path / "dtm.tif", grid=scene["grid"])
    mask, ortho, masked = (_read(tmp_path / n) for n in ("mask.tif", "dsm.tif", "hidden.tif"))
    ds = gdal.Open(str(tmp_path / "mask.tif"))
    assert ds.GetRasterBand(1).GetNoDataValue() == 255
    ds = None
    assert flagged.occlusions == str(tmp_path / "mask.tif") and hidden.occlusions is None
    np.testing.assert_array_equal(mask == 1, (ortho > 0) & (masked == 0))
    np.testing.assert_array_equal(mask == 0, masked > 0)
    np.testing.assert_array_equal(mask == 255, ortho == 0)
    assert (
        flagged.occluded == hidden.occluded == int((mask == 1).sum())
        and flagged.cells == hidden.cells + hidden.occluded
    )
    truth = _read(scene["paths"]["orthoimage"])
    seen, occluded = mask == 0, mask == 1
    gain, offset = np.polyfit(truth[seen], ortho[seen], 1)
    departure = np.abs(ortho - (gain * truth + offset))
    figures.report("cells occluded", 100 * occluded.mean(), "%")
    figures.report("median departure, seen cells", np.median(departure[seen]), "DN")
    figures.report("median departure, occluded cells", np.median(departure[occluded]), "DN")
    assert occluded.sum() > 500
    assert np.median(departure[occluded]) > 2 * np.median(departure[seen])
    raised = {}
    for name, path in (("DSM", tmp_path / "dsm.tif"), ("DTM", tmp_path / "dtm.tif")):
        for cls, label in ((CITY, "town"), (FOREST, "forest")):
            shifts = geometric_error(scene["paths"], str(path), classes=(cls,))
            raised[name, label] = float(np.sqrt(np.mean(np.sum(shifts**2, axis=1))))
            figures.report(
                f"{label} on the {name}: shift against the true orthoimage, RMS ({len(shifts)} patches)",
                raised[name, label],
                "px",
            )
    assert raised["DTM", "town"] > 2 * raised["DSM", "town"] and raised["DTM", "forest"] > 1.3 * raised["DSM", "forest"]


def test_the_mask_says_outside_exactly_where_the_orthoimage_has_no_value(scene, tmp_path):
    """A two-band Float32 image (NaN its nodata) with a block of NaN pixels: the cells that take their values from
    the block have none, and the mask says 255 there as at the image's edge; the same mask path as the orthoimage,
    refused; an empty mask path, no mask."""
    model = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    source = gdal.Open(scene["paths"]["images"]["HRS1"]["imagery"])
    values = source.ReadAsArray().astype(np.float32)
    rows, cols = values.shape
    values[rows // 3 : rows // 2, cols // 3 : cols // 2] = np.nan
    image = str(tmp_path / "float.tif")
    ds = gdal.GetDriverByName("GTiff").Create(image, source.RasterXSize, source.RasterYSize, 2, gdal.GDT_Float32)
    for b in (1, 2):
        ds.GetRasterBand(b).WriteArray(values if b == 1 else 2 * values)
        ds.GetRasterBand(b).SetNoDataValue(np.nan)
    ds = source = None
    out, mask = tmp_path / "ortho.tif", tmp_path / "mask.tif"
    result = orthorectify(image, model, scene["dsm"], OrthoOutputs(out, mask), grid=scene["grid"])
    ortho, codes = gdal.Open(str(out)).ReadAsArray(), _read(mask)
    empty = np.isnan(ortho).all(axis=0)
    assert np.isnan(ortho).any(axis=0).sum() == empty.sum() and (codes == 1).sum() > 500
    orthorectify(
        scene["paths"]["images"]["HRS1"]["imagery"], model, scene["dsm"], tmp_path / "plain.tif", grid=scene["grid"]
    )
    assert (empty & (_read(tmp_path / "plain.tif") > 0)).sum() > 5000  # the block's cells, inside the image
    np.testing.assert_array_equal(codes == 255, empty)
    assert result.cells == int((~empty).sum())
    with pytest.raises(InputError, match="give the mask another name"):
        orthorectify(image, model, scene["dsm"], OrthoOutputs(out, str(out)), grid=scene["grid"])
    assert (
        orthorectify(image, model, scene["dsm"], OrthoOutputs(tmp_path / "o2.tif", ""), grid=scene["grid"]).occlusions
        is None
    )


@pytest.mark.slow
def test_every_execution_gives_the_same_orthoimage(scene, tmp_path):
    model = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    grid = default_grid(model, scene["dsm"])
    images = {}
    for backend, workers in (("threads", 1), ("processes", 2), ("dask", 2)):
        orthorectify(
            scene["paths"]["images"]["HRS1"]["imagery"],
            model,
            scene["dsm"],
            tmp_path / f"{backend}.tif",
            grid=grid,
            settings=OrthoSettings(occluded_nodata=True, tile=256),
            execution=Execution(backend, workers),
        )
        images[backend] = gdal.Open(str(tmp_path / f"{backend}.tif")).ReadAsArray()
    assert (images["threads"] > 0).mean() > 0.5
    for backend in ("processes", "dask"):
        np.testing.assert_array_equal(images[backend], images["threads"])


def keys(t):
    """Keys (a = -0.5) weights at the 4 nodes -1, 0, 1, 2 for fraction t (plain numpy)."""
    d = np.abs(np.array([-1.0, 0.0, 1.0, 2.0]) - t)
    return np.where(d <= 1, 1.5 * d**3 - 2.5 * d**2 + 1, np.where(d < 2, -0.5 * d**3 + 2.5 * d**2 - 4 * d + 2, 0))


def test_resampling_kernels_against_numpy():
    rng = np.random.default_rng(2)
    window = rng.uniform(0, 255, (2, 30, 40)).astype(np.float32)
    col0, row0, cols, rows = -2.0, -2.0, 36.0, 26.0
    col = rng.uniform(-1.0, cols + 1.0, 500)
    row = rng.uniform(-1.0, rows + 1.0, 500)
    inside = (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)
    for method in (BILINEAR, BICUBIC):
        out = np.zeros((2, col.size), np.float32)
        valid = np.zeros(col.size, bool)
        resample_kernel(window, col0, row0, cols, rows, col, row, method, out, valid)
        assert np.array_equal(valid, inside)
        x, y = col[inside] - col0 - 0.5, row[inside] - row0 - 0.5
        for b in range(2):
            if method == BILINEAR:
                expected = ndimage.map_coordinates(window[b].astype(np.float64), [y, x], order=1)
            else:
                expected = [
                    keys(yy % 1) @ window[b, int(yy) - 1 : int(yy) + 3, int(xx) - 1 : int(xx) + 3] @ keys(xx % 1)
                    for xx, yy in zip(x, y)
                ]
            np.testing.assert_allclose(out[b, inside], expected, rtol=1e-5, atol=1e-3)


def test_cancel_leaves_nothing(scene, tmp_path):
    with pytest.raises(CancelledError):
        orthorectify(
            scene["image"],
            scene["hrg"],
            scene["dsm"],
            tmp_path / "cancelled.tif",
            grid=scene["grid"],
            settings=OrthoSettings(tile=256),
            feedback=Feedback(cancel_after=3),
        )
    assert list(tmp_path.iterdir()) == []


def test_bad_input(scene, tmp_path):
    with pytest.raises(InputError, match="does not overlap"):
        far = Dem.constant(300.0, (10.0, 10.0, 10.1, 10.1))
        default_grid(scene["hrg"], far)
    hrs = sensors.load(scene["paths"]["truth_metadata"]["HRS1"])
    with pytest.raises(InputError, match="pixels but its sensor model"):
        orthorectify(scene["image"], hrs, scene["dsm"], tmp_path / "x.tif", grid=scene["grid"])
    with pytest.raises(InputError, match="resampling"):
        orthorectify(
            scene["image"],
            scene["hrg"],
            scene["dsm"],
            tmp_path / "x.tif",
            settings=OrthoSettings(resampling_method="nearest"),
        )
    assert not (tmp_path / "x.tif").exists()
