"""ImageView (issue 6) on a 20000 x 20000 8-bit tiled DEFLATE image at 1280 x 800, offscreen: redraw times
(repaint + processEvents after each step) and the process's peak memory (VmHWM, bound 1 GB = 954 MiB), first
without overviews (GDAL decimated reads), then with external AVERAGE overviews 2-64 from build_overviews."""

import pathlib
import tempfile
import time

from pushbroom.ui.raster_tiles import build_overviews
from tests.helpers.image_view_session import run_in_subprocess, write_textured_raster

SIZE = 20000


def _step(name, seconds):
    return {"operation": name, "redraws": "", "median ms": 1000.0 * seconds, "max ms": "", "peak MB": ""}


def run():
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / "big.tif"
        start = time.perf_counter()
        write_textured_raster(path, SIZE, SIZE)
        rows.append(_step(f"(write the {SIZE} x {SIZE} test image, no overviews)", time.perf_counter() - start))
        rows += [dict(r, operation="no overviews: " + r["operation"]) for r in run_in_subprocess(path)["rows"]]
        start = time.perf_counter()
        build_overviews(path, factors=[2, 4, 8, 16, 32, 64])
        rows.append(_step("(build_overviews 2-64, AVERAGE, external .ovr)", time.perf_counter() - start))
        rows += [dict(r, operation="overviews: " + r["operation"]) for r in run_in_subprocess(path)["rows"]]
    return rows
