"""Issue 40: the Pleiades triplet's three pair DSMs merged (products/merge_dems.py, pushbroom:mergedems). Is the merge
at least as close to the triplet's own DSM as the best pair, and is its precision raster true?

The pair DSMs and their precision rasters as studies/pair_precision.py makes them (the triplet matched densely, its
pairs img_02-img_01 and img_02-img_03 taken from it, img_01-img_03 matched on its own; each pair's refined points
intersected with the supplied RPCs and the product's sigmas; the per-cell DSM of the DEM step at 0.5 m with its
precision raster), and the triplet's own DSM the same way from its points with all their rays. The pairs' RPC biases
differ (docs/validation.md#dense-real): merge_dems co-registers img_02-img_03 and img_01-img_03 to img_02-img_01.

Printed: NMAD of each DSM minus the triplet's, on the cells all of them have; and the precision raster's check by
pair differences, leaving one pair out: the merge of the other two against it, NMAD(d / sqrt(sigma_merge^2 +
sigma_pair^2)) over their common cells (d less its median: the left-out pair keeps its bias), which is 1 where the
precision rasters are true and the two independent."""

import tempfile

import numpy as np

from pushbroom.algorithms.products.merge_dems import MergeOutputs, MergeParams, merge_dems
from pushbroom.algorithms.quality.rasters import open_raster, read_grid
from pushbroom.algorithms.stats import NMAD_SCALE
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid
from pushbroom.algorithms.surface.geotiff import write_float_raster
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from studies.pair_precision import common_grid, pair_cloud, triplet_pairs


def nmad(values: np.ndarray) -> float:
    return float(NMAD_SCALE * np.median(np.abs(values - np.median(values))))


def main() -> None:
    found = triplet_pairs()
    if found is None:
        return
    models, triplet, clouds = found
    clouds["triplet"] = pair_cloud(triplet, models)  # with all its rays
    srs = output_srs(None, clouds["triplet"]["lon"], clouds["triplet"]["lat"])
    xy, grid = common_grid(clouds, srs)
    settings = CellSettings(k=3.0, fallback=False, radius=1)
    folder = tempfile.mkdtemp(prefix="merge-pairs-")
    files = {}
    for name, c in clouds.items():
        cells = cells_on_grid(xy[name][0], xy[name][1], c["h"], c["sigma"], grid, settings, tier=c["tier"])
        files[name] = tuple(
            write_float_raster(f"{folder}/{name}-{kind}.tif", values, grid.geotransform, srs)
            for kind, values in (("h", cells.heights), ("se", cells.precision))
        )
    pairs = [k for k in clouds if k != "triplet"]

    def merged(names: list[str], label: str) -> tuple[np.ndarray, np.ndarray]:
        out = MergeOutputs(f"{folder}/{label}.tif", f"{folder}/{label}-se.tif")
        merge_dems(MergeParams(tuple(files[n][0] for n in names), tuple(files[n][1] for n in names)), out)
        return read(out.dem, grid), read(out.precision, grid)

    heights = {name: read(files[name][0], grid) for name in clouds}
    heights["merged"], _ = merged(pairs, "merged")
    common = np.all([np.isfinite(h) for h in heights.values()], axis=0)
    print(f"NMAD of DSM - the triplet's DSM on the {int(common.sum())} cells all have (m):")
    print("| DSM | NMAD |\n|---|---|")
    for name in [*pairs, "merged"]:
        print(f"| {name} | {nmad((heights[name] - heights['triplet'])[common]):.3f} |")
    print("\nThe precision raster by pair differences, one pair left out (the merge of the other two against it):")
    print("| left out | cells | NMAD(d) m | median sigma of d, m | NMAD(d / sigma) |\n|---|---|---|---|---|")
    for out in pairs:
        h, se = merged([p for p in pairs if p != out], f"without-{out}")
        h_out, se_out = heights[out], read(files[out][1], grid)
        both = np.isfinite(h) & np.isfinite(h_out) & np.isfinite(se) & np.isfinite(se_out)
        d = (h - h_out)[both]
        d -= np.median(d)
        sigma = np.hypot(se, se_out)[both]
        print(f"| {out} | {int(both.sum())} | {nmad(d):.3f} | {np.median(sigma):.3f} | {nmad(d / sigma):.2f} |")


def read(path: str, grid: Grid) -> np.ndarray:
    """Band 1 of `path` on `grid`'s cells (the merge's grid is the first DSM's, the same lattice), NaN for nodata."""
    raster = read_grid(open_raster(path, "DSM"))
    gt, data = raster.geotransform, raster.values
    c0, r0 = int(round((grid.x0 - gt[0]) / grid.cell)), int(round((gt[3] - grid.y0) / grid.cell))
    values = np.full(grid.shape, np.nan)
    rows, cols = min(data.shape[0] - r0, grid.rows), min(data.shape[1] - c0, grid.cols)
    values[:rows, :cols] = data[r0 : r0 + rows, c0 : c0 + cols]
    return values


if __name__ == "__main__":
    main()
