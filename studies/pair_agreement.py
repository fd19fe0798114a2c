"""How far can two pair DSMs of the Pleiades triplet agree? Issue 22 asks the three pair DSMs to agree with an
NMAD of at most 0.25 m; Pushbroom's dense pairs give 0.43 / 0.24 / 0.24 m (tests/real/test_dense_real.py),
region growing's 0.41 / 0.23 / 0.23 m.

Method. Each of the three pairs (img_02-img_01, img_02-img_03, img_01-img_03; the first image the reference)
matched on its own, with the supplied RPCs, by both tools:
- Pushbroom: dense matching (algorithms/dense, default DenseParams), the LSM-refined points intersected
  (surface.intersection), per-cell medians at 0.5 m (cell_dem.cells_on_grid, RADIUS 1, no fill);
- CNES CARS 1.3.0 (build/peers/cars, `make bench-peers` installs it): its default pipeline, 0.5 m, heights
  on the ellipsoid; its DSM warped by GDAL (bilinear, quality.rasters.warp_to) onto Pushbroom's grid.
Per tool, each two pair DSMs' difference over the cells whose centre lies in all three images (at the median
height): median, NMAD, count. Then, were the pairs' errors independent with standard deviations s_a, s_b,
s_c, the differences' variances would be s_a^2 + s_b^2 and so on; the three NMADs give the three s^2, and a
negative one shows that two pairs' errors are correlated: img_02-img_01 and img_02-img_03 share the reference
image, seen from opposite sides, so an error of the reference's template moves their heights in opposite
directions and adds up in their difference.

    QT_QPA_PLATFORM=offscreen .venv/bin/python -m studies.pair_agreement
"""
import pathlib
import sys
import tempfile

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.quality import rasters
from pushbroom.algorithms.quality.rasters import open_raster, warp_to
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.surface.cell_dem import cells_on_grid
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from scripts.bench_peers import CARS, DATA, cars
from tests.helpers.real_dsm import cut, footprint_mask, refined_dense_points

#: the triplet in the order both tools pair it (the reference first), and the three pairs as indices
PATHS = [DATA / f"img_0{k}.tif" for k in (2, 1, 3)]
NAMES = ("img_02", "img_01", "img_03")
PAIRS = ((0, 1), (0, 2), (1, 2))
CELL = 0.5


def pushbroom_pair(models, a, b, folder):
    """(lon, lat, h) of the refined dense points of the pair (a, b)."""
    points, _ = refined_dense_points([PATHS[a], PATHS[b]], [models[a], models[b]], [NAMES[a], NAMES[b]], folder,
                                     models[a].height_range)
    result = cut({1: models[a], 2: models[b]}, points.observations)
    ok = result.ok
    return result.lon[ok], result.lat[ok], result.h[ok]


def implied_sigmas(nmad):
    """s^2 of the three pairs from the NMADs of (a-b, a-c, b-c) were their errors independent."""
    ab, ac, bc = (v * v for v in nmad)
    return ((ab + ac - bc) / 2, (ab + bc - ac) / 2, (ac + bc - ab) / 2)


def run():
    if not CARS.exists():
        sys.exit(f"{CARS} is missing: run make bench-peers, which installs CARS 1.3.0 into build/peers/cars")
    models = [sensors.load(p) for p in PATHS]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        clouds = {pair: pushbroom_pair(models, *pair, tmp / f"dense-{pair[0]}{pair[1]}") for pair in PAIRS}
        lon, lat, h = (np.concatenate([c[k] for c in clouds.values()]) for k in range(3))
        srs = output_srs(None, lon, lat)
        x, y = reproject(lon, lat, wgs84(), srs)
        grid = Grid.covering(x, y, CELL)
        inside = footprint_mask(grid, srs, models, float(np.median(h)))
        dsms = {"Pushbroom": {}, "CARS 1.3.0": {}}
        for pair, (plon, plat, ph) in clouds.items():
            px, py = reproject(plon, plat, wgs84(), srs)
            dsms["Pushbroom"][pair] = cells_on_grid(px, py, ph, None, grid, radius=1).heights.astype(float)
            _, dsm = cars(tmp / f"cars-{pair[0]}{pair[1]}", {NAMES[k]: PATHS[k] for k in pair},
                          [(NAMES[pair[0]], NAMES[pair[1]])], CELL)
            dsms["CARS 1.3.0"][pair] = warp_to(open_raster(dsm, "CARS's DSM"), rasters.Grid(
                dsms["Pushbroom"][pair], grid.geotransform, srs), "bilinear")
    for tool, pairs in dsms.items():
        nmads = []
        for i, p in enumerate(PAIRS):
            for q in PAIRS[i + 1:]:
                s = summarize((pairs[p] - pairs[q])[inside])
                nmads.append(s.nmad)
                print(f"{tool}: {NAMES[p[0]]}-{NAMES[p[1]]} minus {NAMES[q[0]]}-{NAMES[q[1]]}: N {s.n}, median "
                      f"{s.median:+.3f} m, NMAD {s.nmad:.3f} m")
        print(f"{tool}: implied s^2 of the pairs were their errors independent: "
              + ", ".join(f"{NAMES[p[0]]}-{NAMES[p[1]]} {v:+.4f} m^2" for p, v in zip(PAIRS, implied_sigmas(nmads))))


if __name__ == "__main__":
    run()
