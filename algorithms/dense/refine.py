"""Sub-pixel refinement of dense image-2 positions by least-squares matching in the original images.

Each dense point (x1, y1) -> (x2, y2) is matched again by LSM (matching.lsm through
region_growing.transfer_points: an affine template of GrowParams.template px on the resolution-adapted
images), starting at its dense position with the models' local affine at the middle height. The LSM result
replaces the dense position where it passes region growing's acceptance criteria (rho, error ellipse,
iterations) and lies within `max_shift` px of the dense position: a larger move means the template straddles
two surfaces (a forest edge, a building), where the 5 x 5 census window's position is the better one. A
refined point carries LSM's rho and error-ellipse semi-axes (its precision); the others keep NaN.

Measured on the simulated triplet (docs/validation.md#dense-matching): LSM halves the dense position's error
on open ground where it is accepted, and makes it worse within a template of a height step."""
import numpy as np

from ..matching.pair_geometry import local_affine
from ..matching.params import GrowParams
from ..matching.records import PAIR_DTYPE
from ..matching.region_growing import transfer_points


def refine_positions(image1, image2, model1, model2, x1, y1, x2, y2, height_range, template=19, max_shift=0.5):
    """(x2, y2, rho, semi_major, semi_minor): the refined image-2 positions of points (x1, y1) matched at
    (x2, y2) (NaN: unmatched, left as they are), with LSM's quality where refined (NaN elsewhere)."""
    x2, y2 = np.array(x2, float), np.array(y2, float)
    rho, major, minor = (np.full(x2.size, np.nan, np.float32) for _ in range(3))
    idx = np.flatnonzero(np.isfinite(x2) & np.isfinite(y2))
    if idx.size == 0:
        return x2, y2, rho, major, minor
    h_m = 0.5 * (height_range[0] + height_range[1])
    _, _, a1, a2, a4, a5 = local_affine(model1, model2, x1[idx], y1[idx], h_m)
    guide = np.zeros(idx.size, PAIR_DTYPE)
    guide["x1"], guide["y1"], guide["x2"], guide["y2"] = x1[idx], y1[idx], x2[idx], y2[idx]
    guide["a1"], guide["a2"], guide["a4"], guide["a5"] = a1, a2, a4, a5
    params = GrowParams(template=int(template), max_shift=float(max_shift))
    records, accepted = transfer_points(image1, image2, model1, model2, x1[idx], y1[idx], params, height_range,
                                        guide=guide)
    take = idx[accepted]
    r = records[accepted]
    x2[take], y2[take] = r["x2"], r["y2"]
    rho[take], major[take], minor[take] = r["rho"], r["semi_major"], r["semi_minor"]
    return x2, y2, rho, major, minor
