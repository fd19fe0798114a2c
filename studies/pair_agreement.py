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
height): median, NMAD, count; and, with each pair's height per px of parallax (m_a, from the RPCs at the scene
centre), the parallax precision per pair that NMAD means were the pairs independent and equally precise in px,
NMAD / sqrt(m_a^2 + m_b^2), beside what 0.25 m would need. Then, were the pairs' errors independent with
standard deviations s_a, s_b, s_c, the differences' variances would be s_a^2 + s_b^2 and so on; the three
NMADs give the three s^2, and a negative one shows that two pairs' errors are correlated: img_02-img_01 and
img_02-img_03 share the reference image, seen from opposite sides, so an error of the reference's template
moves their heights in opposite directions and adds up in their difference.

    QT_QPA_PLATFORM=offscreen .venv/bin/python -m studies.pair_agreement [TEMPLATE ...]

(Pushbroom at each LSM template size given in px, default 19.)
"""

import pathlib
import sys
import tempfile

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.quality import rasters
from pushbroom.algorithms.quality.rasters import open_raster, warp_to
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.surface.cell_dem import CellSettings, cells_on_grid
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_grid import Grid
from scripts.bench_peers import CARS, DATA, cars
from tests.helpers.real_dsm import cut, footprint_mask, refined_dense_points

#: the triplet in the order both tools pair it (the reference first), and the three pairs as indices
PATHS = [DATA / f"img_0{k}.tif" for k in (2, 1, 3)]
NAMES = ("img_02", "img_01", "img_03")
PAIRS = ((0, 1), (0, 2), (1, 2))
CELL = 0.5


def pushbroom_pair(models, a, b, folder, template):
    """(lon, lat, h) of the refined dense points of the pair (a, b), LSM's template `template` px."""
    points, _ = refined_dense_points(
        [PATHS[a], PATHS[b]],
        [models[a], models[b]],
        [NAMES[a], NAMES[b]],
        folder,
        models[a].height_range,
        DenseParams(template=template),
    )
    result = cut({1: models[a], 2: models[b]}, points.observations)
    ok = result.ok
    return result.lon[ok], result.lat[ok], result.h[ok]


def metres_per_px(models, a, b):
    """Height (m) per px of parallax of the pair (a, b) at the reference image's centre and the RPCs' mean
    height: the pair's image motions for 1 m up, their difference's length."""
    cols, rows = models[0].size
    h = float(np.mean(models[0].height_range))
    lon, lat = models[0].image_to_ground(np.array([cols / 2]), np.array([rows / 2]), np.array([h]))
    motion = [
        np.subtract(
            models[k].ground_to_image(lon, lat, np.array([h + 1.0])), models[k].ground_to_image(lon, lat, np.array([h]))
        ).ravel()
        for k in (a, b)
    ]
    return 1.0 / float(np.hypot(*(motion[1] - motion[0])))


def implied_sigmas(nmad):
    """s^2 of the three pairs from the NMADs of (a-b, a-c, b-c) were their errors independent."""
    ab, ac, bc = (v * v for v in nmad)
    return ((ab + ac - bc) / 2, (ab + bc - ac) / 2, (ac + bc - ab) / 2)


def run(templates=(19,)):
    """The study (module docstring) with Pushbroom's LSM template at each of `templates` px."""
    if not CARS.exists():
        sys.exit(f"{CARS} is missing: run make bench-peers, which installs CARS 1.3.0 into build/peers/cars")
    models = [sensors.load(p) for p in PATHS]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        clouds = {
            t: {pair: pushbroom_pair(models, *pair, tmp / f"dense-{t}-{pair[0]}{pair[1]}", t) for pair in PAIRS}
            for t in templates
        }
        first = clouds[templates[0]]
        lon, lat, h = (np.concatenate([c[k] for c in first.values()]) for k in range(3))
        srs = output_srs(None, lon, lat)
        x, y = reproject(lon, lat, wgs84(), srs)
        grid = Grid.covering(x, y, CELL)
        inside = footprint_mask(grid, srs, models, float(np.median(h)))
        dsms = {f"Pushbroom, {t} px template": {} for t in templates}
        for t in templates:
            for pair, (plon, plat, ph) in clouds[t].items():
                px, py = reproject(plon, plat, wgs84(), srs)
                dsms[f"Pushbroom, {t} px template"][pair] = cells_on_grid(
                    px, py, ph, None, grid, CellSettings(radius=1)
                ).heights.astype(float)
        dsms["CARS 1.3.0"] = {}
        for pair in PAIRS:
            _, dsm = cars(
                tmp / f"cars-{pair[0]}{pair[1]}",
                {NAMES[k]: PATHS[k] for k in pair},
                [(NAMES[pair[0]], NAMES[pair[1]])],
                CELL,
            )
            dsms["CARS 1.3.0"][pair] = warp_to(
                open_raster(dsm, "CARS's DSM"),
                rasters.Grid(np.zeros((grid.rows, grid.cols)), grid.geotransform, srs),
                "bilinear",
            )
    scale = {p: metres_per_px(models, *p) for p in PAIRS}
    for p, m in scale.items():
        print(f"{NAMES[p[0]]}-{NAMES[p[1]]}: {m:.2f} m of height per px of parallax")
    for tool, pairs in dsms.items():
        nmads = []
        for i, p in enumerate(PAIRS):
            for q in PAIRS[i + 1 :]:
                s = summarize((pairs[p] - pairs[q])[inside])
                nmads.append(s.nmad)
                px = s.nmad / np.hypot(scale[p], scale[q])  # each pair's parallax NMAD, were they independent
                print(
                    f"{tool}: {NAMES[p[0]]}-{NAMES[p[1]]} minus {NAMES[q[0]]}-{NAMES[q[1]]}: N {s.n}, median "
                    f"{s.median:+.3f} m, NMAD {s.nmad:.3f} m: {px:.3f} px of parallax per pair (0.25 m needs "
                    f"{0.25 / np.hypot(scale[p], scale[q]):.3f} px)"
                )
        print(
            f"{tool}: implied s^2 of the pairs were their errors independent: "
            + ", ".join(f"{NAMES[p[0]]}-{NAMES[p[1]]} {v:+.4f} m^2" for p, v in zip(PAIRS, implied_sigmas(nmads)))
        )


if __name__ == "__main__":
    run(tuple(int(a) for a in sys.argv[1:]) or (19,))
