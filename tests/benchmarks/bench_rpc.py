"""RPC00B evaluation speed: RpcModel against GDAL's RPC transformer, both directions.

On the Pleiades triplet image img_01.tif of the real test data (benchutil.SHARED_DATA); points spread over
the image and the RPC's height range; best of 3 runs after a warm-up (numba compiled or loaded from its cache).
GDAL's image -> ground runs with RPC_PIXEL_ERROR_THRESHOLD=1e-9 px, comparable to RpcModel's
1e-8 px (GDAL's default, 0.1 px, is faster and coarser)."""

import numpy as np
from osgeo import gdal

from pushbroom.algorithms import sensors
from tests.benchmarks.benchutil import SHARED_DATA, best_time

IMAGE = SHARED_DATA / "pleiades_triplet" / "img_01.tif"
N_OURS = 1_000_000
N_GDAL = 100_000


def sample_points(model, n, seed=0):
    """n image points (col, row, h) spread over the raster and the RPC's height range."""
    rng = np.random.default_rng(seed)
    return (rng.uniform(0, model.size[0], n), rng.uniform(0, model.size[1], n), rng.uniform(*model.height_range, n))


def run():
    if not IMAGE.exists():
        return [{"direction": f"skipped: {IMAGE} not available"}]
    gdal.UseExceptions()
    model = sensors.load(IMAGE)
    ds = gdal.Open(str(IMAGE))
    transformer = gdal.Transformer(ds, None, ["METHOD=RPC", "RPC_PIXEL_ERROR_THRESHOLD=1e-9"])
    col, row, h = sample_points(model, N_OURS)
    lon, lat = model.image_to_ground(col, row, h)
    image_pts = np.column_stack([col, row, h])[:N_GDAL]
    ground_pts = np.column_stack([lon, lat, h])[:N_GDAL]
    cases = [
        (
            "ground -> image",
            lambda: model.ground_to_image(lon, lat, h),
            lambda: transformer.TransformPoints(1, ground_pts),
        ),
        (
            "image -> ground",
            lambda: model.image_to_ground(col, row, h),
            lambda: transformer.TransformPoints(0, image_pts),
        ),
    ]
    rows = []
    for direction, ours, theirs in cases:
        ours_rate = N_OURS / best_time(ours)
        gdal_rate = N_GDAL / best_time(theirs)
        rows.append(
            {
                "direction": direction,
                "pushbroom points/s": ours_rate,
                "GDAL points/s": gdal_rate,
                "pushbroom / GDAL": ours_rate / gdal_rate,
            }
        )
    return rows


if __name__ == "__main__":
    for r in run():
        print("  ".join(f"{k}: {v:.4g}" if isinstance(v, float) else f"{k}: {v}" for k, v in r.items()))
