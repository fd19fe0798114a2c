"""CNES Bulldozer's speed against the width of the DSM it is given: why extractdtm's windows have a number of columns
that is a multiple of 16 but not of 128 (products/extract_dtm.py, DtmParams.window).

The 15 km simulated scene's true DSM (bench_region_growing.scene), warped to its UTM zone at 5 m; windows of 2000
rows and WIDTHS columns cut from one place of it, each given to Bulldozer 1.2.0's dsm_to_dtm (one worker, the step's
settings) in this process, one after the other. Rows: columns, seconds, microseconds per cell, and the time per cell
against that of the width extractdtm uses for TILE 2048 (2032).

    python -m tests.benchmarks.bench_bulldozer_widths
"""

import pathlib
import tempfile
import time

from osgeo import gdal

from pushbroom.algorithms.products.extract_dtm import DtmParams
from tests.benchmarks.bench_chain_memory import _utm_of
from tests.benchmarks.bench_region_growing import scene

#: columns of the windows: multiples of 16 (not of 128), odd, and multiples of 128 and 2048
WIDTHS = (2032, 2040, 2047, 2048, 2056, 2080, 2112, 2176)
ROWS = 2000
CORNER = (800, 800)


def run() -> list[dict]:
    from bulldozer.pipeline.bulldozer_pipeline import dsm_to_dtm

    gdal.UseExceptions()
    dsm = scene(15.0) / "dsm.tif"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        utm = folder / "dsm-utm.tif"
        gdal.Warp(str(utm), str(dsm), dstSRS=_utm_of(dsm), xRes=5, yRes=5, resampleAlg="bilinear", errorThreshold=0)
        for width in WIDTHS:
            cut = folder / f"dsm-{width}.tif"
            gdal.Translate(str(cut), str(utm), srcWin=[*CORNER, width, ROWS])
            start = time.perf_counter()
            dsm_to_dtm(
                dsm_path=str(cut),
                output_dir=str(folder / f"out-{width}"),
                generate_dhm=False,
                max_object_size=DtmParams().max_object_size,
                max_ground_slope=DtmParams().max_ground_slope,
                nb_max_workers=1,
                developer_mode=False,
            )
            seconds = time.perf_counter() - start
            rows.append({"columns": width, "seconds": seconds, "us per cell": 1e6 * seconds / (width * ROWS)})
    reference = rows[0]["us per cell"]
    for row in rows:
        row["per cell / 2032's"] = f"x {row['us per cell'] / reference:.2f}"
    return rows


if __name__ == "__main__":
    from tests.benchmarks.run_all import markdown_table

    print(markdown_table(run()))
