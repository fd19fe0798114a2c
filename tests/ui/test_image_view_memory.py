"""Issue 6 acceptance: an ImageView on a 20000 x 20000 image (tiled DEFLATE, textured) at 1280 x 800 keeps its
process below 1 GB through zooms from fit to 4:1, pans across the image and 200 jumps at 1:1 (the tile caches
filled to their bounds), without overviews (decimated reads) and with them (build_overviews). The redraw times
are measured in benchmarks/bench_image_view.py."""

import pytest

from pushbroom.ui.raster_tiles import CACHE_BYTES, build_overviews
from tests.helpers.image_view_session import run_in_subprocess, write_textured_raster

LIMIT_MB = 1e9 / 2**20


@pytest.mark.slow
def test_20000_px_image_stays_below_1_gb(tmp_path, figures):
    path = write_textured_raster(tmp_path / "big.tif", 20000, 20000)
    plain = run_in_subprocess(path, pans=20, jumps=200)
    assert plain["levels"] == 8  # full resolution + 7 decimated levels
    build_overviews(path, factors=[2, 4, 8, 16, 32, 64])
    with_overviews = run_in_subprocess(path, pans=20, jumps=200)
    for label, result in (("without overviews", plain), ("with overviews", with_overviews)):
        figures.table(
            f"peak memory (MB) after each operation, {label}",
            [{"operation": row["operation"], "peak MB": round(row["peak MB"])} for row in result["rows"]],
        )
        assert result["cache_mb"] <= CACHE_BYTES / 2**20
        assert result["cache_mb"] > 0.8 * CACHE_BYTES / 2**20  # the cache was filled: the bound was tested
        assert result["peak_mb"] < LIMIT_MB
