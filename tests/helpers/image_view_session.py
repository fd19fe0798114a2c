"""A large textured test raster and a scripted ImageView session (zooms and pans at 1280 x 800, each redraw
timed) that runs in its own process, so that its peak memory (VmHWM) is the view's alone. Shared by
test_image_view_memory.py and benchmarks/bench_image_view.py.

Run as a script: image_view_session.py RASTER RESULT_JSON [--pans N] [--jumps N] writes one JSON object to
RESULT_JSON: {"rows": [...], "peak_mb": ..., "cache_mb": ..., "levels": ...}."""

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

WIDTH, HEIGHT = 1280, 800
CREATION = ["TILED=YES", "COMPRESS=DEFLATE", "ZLEVEL=1", "NUM_THREADS=ALL_CPUS", "BIGTIFF=IF_SAFER"]


def write_textured_raster(path, cols, rows, seed=0):
    """8-bit tiled DEFLATE GeoTIFF (no overviews) written one row of 256 x 256 blocks at a time: a smooth
    wave, a pattern of 97 x 61 px fields and uniform noise (every block different)."""
    from osgeo import gdal

    gdal.UseExceptions()
    rng = np.random.default_rng(seed)
    ds = gdal.GetDriverByName("GTiff").Create(os.fspath(path), cols, rows, 1, gdal.GDT_Byte, CREATION)
    band = ds.GetRasterBand(1)
    x = np.arange(cols)
    wave_x, field_x = np.sin(x * 0.0021), (x // 97).astype(np.int16)
    for r0 in range(0, rows, 256):
        y = np.arange(r0, min(r0 + 256, rows))
        wave = 50.0 * np.cos(y * 0.0017)[:, None] * wave_x[None, :]
        fields = ((field_x[None, :] + (y // 61).astype(np.int16)[:, None]) % 7) * 9
        noise = rng.integers(0, 48, (len(y), cols), dtype=np.uint8)
        band.WriteArray((70.0 + wave + fields).astype(np.uint8) + noise, 0, r0)
        ds.FlushCache()
    ds = None
    return path


def peak_mb():
    """This process's peak resident memory (VmHWM) in MiB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError("no VmHWM in /proc/self/status")


def session(path, pans=62, jumps=200):
    """Open `path` in a shown 1280 x 800 ImageView and time redraws (repaint + processEvents) after each
    step: zoom from fit to 1:1 and 4:1 (x1.25 steps), pans of a quarter view across the image at 4:1 and
    1:1 (there and back: the way back is cached), jumps to random places at 1:1, zoom out to fit."""
    from qgis.PyQt.QtWidgets import QApplication

    from pushbroom.ui.image_view import ImageView

    app = QApplication.instance() or QApplication([])
    view = ImageView()
    view.resize(WIDTH, HEIGHT)
    view.show()
    app.processEvents()
    rows = []

    def timed(name, steps):
        times = []
        for step in steps:
            start = time.perf_counter()
            step()
            view.repaint()
            app.processEvents()
            times.append(1000.0 * (time.perf_counter() - start))
        rows.append(
            {
                "operation": name,
                "redraws": len(times),
                "median ms": statistics.median(times),
                "max ms": max(times),
                "peak MB": peak_mb(),
            }
        )

    timed("open (auto stretch) + first redraw at fit", [lambda: view.open(path)])
    cols, rows_ = view.image_size
    fit = view.zoom

    def zoom_steps(target, factor):
        n = int(np.ceil(np.log(target / view.zoom) / np.log(factor)))
        return [lambda: view.set_zoom(view.zoom * factor, (0.6 * WIDTH, 0.45 * HEIGHT))] * max(n, 0)

    timed(f"zoom in x1.25, {fit:.3f} (fit) -> 1:1", zoom_steps(1.0, 1.25))
    timed("zoom in x1.25, 1:1 -> 4:1", zoom_steps(4.0, 1.25))
    quarter = WIDTH / 4.0

    def pans_at(zoom, sign, n):
        def go():
            view.center_on(view.view_center[0] + sign * quarter / zoom, view.view_center[1], zoom)

        return [go] * n

    view.center_on(0.0, rows_ / 2.0, 4.0)
    timed("pan 1/4 view at 4:1", pans_at(4.0, 1, pans))
    view.center_on(0.0, rows_ / 3.0, 1.0)
    timed("pan 1/4 view at 1:1 across the image", pans_at(1.0, 1, pans))
    timed("pan back at 1:1 (cached tiles)", pans_at(1.0, -1, pans))
    rng = np.random.default_rng(1)
    spots = rng.uniform(0.0, 1.0, (jumps, 2)) * (cols, rows_)
    timed("jump to a random place at 1:1", [lambda p=p: view.center_on(p[0], p[1], 1.0) for p in spots])
    timed("zoom out x1.25, 1:1 -> fit", zoom_steps(fit, 1 / 1.25))
    result = {
        "rows": rows,
        "peak_mb": peak_mb(),
        "cache_mb": view.reader.cache.nbytes / 2**20,
        "levels": len(view.reader.levels),
    }
    view.clear()
    return result


def run_in_subprocess(path, pans=62, jumps=200):
    """session() in a fresh Python process (offscreen Qt); returns its JSON result."""
    import subprocess
    import tempfile

    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    with tempfile.TemporaryDirectory() as folder:
        result = os.path.join(folder, "session.json")
        proc = subprocess.run(
            [
                sys.executable,
                os.path.abspath(__file__),
                os.fspath(path),
                result,
                "--pans",
                str(pans),
                "--jumps",
                str(jumps),
            ],
            env=env,
            capture_output=True,
            text=True,
        )
        if proc.returncode != 0:
            raise RuntimeError(
                f"the ImageView session failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
            )
        with open(result, encoding="utf-8") as f:
            return json.load(f)


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("raster")
    parser.add_argument("result")
    parser.add_argument("--pans", type=int, default=62)
    parser.add_argument("--jumps", type=int, default=200)
    args = parser.parse_args()
    from pushbroom.algorithms.atomic import write_text

    write_text(args.result, json.dumps(session(args.raster, args.pans, args.jumps)))
