"""What the dense studies share: the 3 km simulated triplet's dense points intersected with the TRUE models (the
error is the matching's alone), and the dense pipeline model's 10 m DSM of them (surface/dem_tiles.py, method
"cells", FALLBACK off, RADIUS 1, FILL 10) at the evaluation cells of tests/helpers/dsm_comparison.py."""

import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import numpy as np

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.dense import precision
from pushbroom.algorithms.dense.dense_strategy import match_dense_tiles
from pushbroom.algorithms.dense.epipolar import EpipolarGrid
from pushbroom.algorithms.dense.pair_tile import match_pair_tile
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.dense.refine import Conjugates, Refined, refine_positions
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.matching.imagery import as_image
from pushbroom.algorithms.matching.pair_geometry import ImagePair
from pushbroom.algorithms.matching.points import MultiPoints
from pushbroom.algorithms.sigmas import IMAGE_SIGMA
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.dem_tiles import dem_from_point_cloud
from pushbroom.algorithms.surface.local_spread import local_spread
from pushbroom.algorithms.surface.pointcloud import write_las
from pushbroom.algorithms.surface.tin_dem import DemParams
from pushbroom.algorithms.surface.tin_grid import Grid
from scripts.bench_peers import sample
from tests.helpers.dsm_comparison import CELL, NAMES, Truth
from tests.helpers.pleiades_scene import NAMES as TRIPLET_NAMES
from tests.helpers.real_dsm import dense_points as real_dense_points

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
#: real pairs (first image, second image) of ../shared/data
REAL = {
    "Pleiades triplet, img_02 -> img_01": ("pleiades_triplet/img_02.tif", "pleiades_triplet/img_01.tif"),
    "Ventoux pair": ("pleiades_pair_ventoux/left_image.tif", "pleiades_pair_ventoux/right_image.tif"),
}
#: the Pleiades triplet in combination order (the reference img_02 first) and the heights its search finds
TRIPLET = [SHARED / "pleiades_triplet" / f"{name}.tif" for name in TRIPLET_NAMES]
TRIPLET_HEIGHTS = (40.0, 535.0)
#: the refinement before its largest shift became 1 px (studies/README.md#dense_variance_test), as studies measured it
BEFORE = {"max_shift": 0.5}


def triplet_points(params: DenseParams | None = None) -> tuple[list, MultiPoints] | None:
    """(models, dense points) of the Pleiades triplet (DenseParams `params`, default the defaults; 2 threads, over
    TRIPLET_HEIGHTS); None, and said, where the data are absent."""
    if not all(f.exists() for f in TRIPLET):
        print(f"the Pleiades triplet is not in {SHARED}")
        return None
    models = [sensors.load(f) for f in TRIPLET]
    points, _ = real_dense_points(TRIPLET, models, TRIPLET_NAMES, tempfile.mkdtemp(), TRIPLET_HEIGHTS, params)
    return models, points


class TruthCloud(NamedTuple):
    """Dense points, their intersection with the true models, and the matching's seconds."""

    points: MultiPoints
    result: intersection.Intersection
    seconds: float

    def rho(self) -> np.ndarray:
        """Per intersected point (result order), its rho_min (NaN: not refined in every position)."""
        pts = self.points.points
        return pts["rho_min"][np.searchsorted(pts["id"], self.result.point)]


def dense_points(paths: dict, params: DenseParams) -> tuple[MultiPoints, float]:
    """Dense matching (DenseParams `params`, 2 threads) of the simulated triplet `paths` with its supplied models over
    the DSM's height range +- 100 m: (the points, the matching's seconds)."""
    images = [paths["images"][n]["imagery"] for n in NAMES]
    models = [sensors.load(paths["images"][n]["metadata"]) for n in NAMES]
    lo, hi = read_dem(paths["dsm"]).height_range
    t = time.perf_counter()
    parts, _ = match_dense_tiles(
        images,
        models,
        tempfile.mkdtemp() + "/dense",
        params=params,
        height_range=(lo - 100.0, hi + 100.0),
        execution=Execution("threads", 2),
    )
    seconds = time.perf_counter() - t
    return MultiPoints(
        np.concatenate([p.points for p in parts]), np.concatenate([p.observations for p in parts])
    ), seconds


def intersect_truth(
    points: MultiPoints, truth: Truth, sigma: np.ndarray | float = IMAGE_SIGMA
) -> intersection.Intersection:
    """The points intersected with `truth`'s models, with the image `sigma` (px; per observation or one)."""
    obs = points.observations
    lo, hi = truth.dsm.height_range
    return intersection.intersect(
        truth.models,
        intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"], sigma),
        h0=0.5 * (lo + hi),
    )


def truth_cloud(paths: dict, truth: Truth, params: DenseParams) -> TruthCloud:
    """dense_points of the simulated triplet `paths`, every point intersected with `truth`'s models."""
    points, seconds = dense_points(paths, params)
    return TruthCloud(points, intersect_truth(points, truth), seconds)


def model_dem(cloud: TruthCloud, truth: Truth, folder: str) -> tuple[np.ndarray, np.ndarray]:
    """(DSM - true DSM, the mask: 0 own points, 2 the cells around, 1 filled) at `truth`'s evaluation cells, of the
    dense pipeline model's 10 m DSM of `cloud`, written to `folder`."""
    res = cloud.result
    ok = res.ok
    x, y = reproject(res.lon[ok], res.lat[ok], wgs84(), truth.srs)
    fields = {"rho": cloud.rho()[ok].astype(np.float32), "rays": res.rays[ok].astype(np.uint8)}
    write_las(f"{folder}/dense.las", x, y, res.h[ok], fields, truth.srs)
    dem_from_point_cloud(
        f"{folder}/dense.las",
        f"{folder}/dem.tif",
        DemParams(cell=CELL, method="cells", fallback=False, fill=10.0, radius=1),
        mask_path=f"{folder}/mask.tif",
    )
    return sample(f"{folder}/dem.tif", truth) - truth.h, sample(f"{folder}/mask.tif", truth)


def evaluation_grid(truth: Truth) -> tuple[Grid, np.ndarray, np.ndarray]:
    """A CELL m grid (tin_grid.Grid) holding `truth`'s evaluation cells one cell inside its edges, and each
    evaluation cell's (row, column) on it."""
    x0, y0 = np.floor(truth.x.min() / CELL) * CELL - CELL, np.ceil(truth.y.max() / CELL) * CELL + CELL
    grid = Grid(
        float(x0), float(y0), CELL, int((truth.x.max() - x0) // CELL) + 3, int((y0 - truth.y.min()) // CELL) + 3
    )
    return grid, np.floor((grid.y0 - truth.y) / CELL).astype(int), np.floor((truth.x - grid.x0) / CELL).astype(int)


def with_template_spread(
    sigma_h: np.ndarray, x: np.ndarray, y: np.ndarray, h: np.ndarray, refined: np.ndarray, reference, spread: float
) -> tuple[np.ndarray, np.ndarray]:
    """(sigma_h with the refined points' spread term added as intersectpoints adds it, the spread):
    precision.with_spread of factor `spread` (Calibration.spread) over surface/local_spread.py, R at the centre of the
    `reference` model at the refined points' median height; x, y in metres; the spread NaN where not refined."""
    cols, rows = reference.size
    radius = precision.spread_radius(reference, cols / 2, rows / 2, float(np.median(h[refined])))
    s = np.full(len(h), np.nan)
    s[refined] = local_spread(x[refined], y[refined], h[refined], x[refined], y[refined], radius)
    out = np.array(sigma_h, float)
    out[refined] = precision.with_spread(out[refined], s[refined], spread)
    return out, s


def rms(v: np.ndarray) -> float:
    """RMS of the finite values (NaN for none)."""
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")


class RealTile(NamedTuple):
    """The central 512 px tile of a real pair's first image: its lattice's dense positions, their LSM refinement
    (DenseParams.refinement, without the isolation and bias tests) and the tile's epipolar grid."""

    label: str
    first: Path
    dense: Conjugates
    refined: Refined
    grid: EpipolarGrid


def real_tiles(params: DenseParams) -> Iterator[RealTile]:
    """The RealTile of each pair of REAL, dense matching with `params`; a pair absent from SHARED is said and
    skipped."""
    for label, files in REAL.items():
        paths = [SHARED / f for f in files]
        if not all(p.exists() for p in paths):
            print(f"{label}: not in {SHARED}")
            continue
        models = [sensors.load(p) for p in paths]
        images = [as_image(p, saturation=True) for p in paths]
        cols, rows = models[0].size
        box = (cols // 2 - 256, rows // 2 - 256, cols // 2 + 256, rows // 2 + 256)
        heights = models[0].height_range
        x1, y1, x2, y2, info = match_pair_tile(images[0], images[1], models[0], models[1], box, heights, params)
        dense = Conjugates(x1, y1, x2, y2)
        pair = ImagePair(images[0], images[1], models[0], models[1])
        refined = refine_positions(pair, dense, info["grid"].heights[::2], params.refinement())
        yield RealTile(label, paths[0], dense, refined, info["grid"])
