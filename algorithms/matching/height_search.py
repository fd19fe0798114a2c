"""The terrain's height range found by matching, for a block made without a DEM and without a height.

Model. Matching searches along each ray between two heights; outside them it finds nothing (the Pleiades
triplet at its RPC's mean height +- 500 m gave no seed at all). With no height known, the search runs once,
sparsely, over the whole height range the orientation is valid for:
1. the validity range: an RPC's HEIGHT_OFF +- HEIGHT_SCALE (RpcModel.height_range); a rigorous SPOT model has
   none in its DIMAP, so the Earth's: EARTH_HEIGHTS (ellipsoidal, the Dead Sea to Mount Everest with the geoid's
   extremes);
2. interest points in up to WINDOWS x WINDOWS windows of WINDOW px spread evenly over image 1 (all of a small
   image), each matched in every other image by seeds.automatic_seeds over that range (NCC along the whole
   predicted path, uniqueness, LSM and its acceptance criteria), each window and image one task on the chosen
   execution (execution.run_tasks): memory follows the window, not the scene;
3. every matched pair intersected with the two models (surface.intersection);
4. the robust range: heights further than OUTLIER_NMAD robust sigmas (1.4826 MAD, at least MIN_SPREAD m)
   from their median are dropped as mismatches; of the rest, the PERCENTILES (the highest and lowest few
   points carry any mismatch left), widened on each side by MARGIN of their span and at least MIN_MARGIN m
   (the peaks and valleys between the sampled points), clipped to the validity range.

Failure modes: InputError for fewer than two images (nothing to intersect), or fewer than MIN_POINTS
heights (no overlap, no texture, or an orientation too far off for the +-3 px search across the path); the
message asks for a DEM or a height. CancelledError through the feedback.

Reference: the seeds of C. Heipke, W. Kornus, A. Pfannenstein, "The evaluation of MEOSS airborne
three-line scanner imagery", IAPRS 29(B1), 1992 (section 2), searched here over the whole range."""

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from ..execution import run_tasks
from ..surface import intersection
from .imagery import as_image
from .pair_geometry import ImagePair
from .params import GrowParams
from .seeds import automatic_seeds

#: m: ellipsoidal heights of the Earth's land surface (Dead Sea -430 m with the geoid's -107 m under it to
#: Everest 8849 m with +-30 m of geoid), the validity range of a model that states none
EARTH_HEIGHTS = (-550.0, 8900.0)
WINDOWS = 4  # windows per side of image 1
WINDOW = 512  # px: a window's side
MIN_POINTS = 10  # heights the range needs
CELL = 24  # px: at most one interest point per CELL x CELL px of a window
OUTLIER_NMAD = 8.0  # robust sigmas beyond which a height is a mismatch
MIN_SPREAD = 25.0  # m: the robust sigma below which the mismatch test does not tighten
PERCENTILES = (1.0, 99.0)
MARGIN = 1.0  # of the span, on each side
MIN_MARGIN = 100.0  # m, on each side


class HeightSearch(NamedTuple):
    """The range found, and how."""

    height_range: tuple  # (h_min, h_max), ellipsoidal m
    median: float  # the median matched height (m)
    points: int  # heights used
    rejected: int  # heights dropped as mismatches
    searched: tuple  # the validity range searched


def validity_range(models):
    """(h_min, h_max) the models are all valid for: the intersection of the RPCs' validity ranges, the Earth's
    heights for a model that states none."""
    ranges = [getattr(m, "height_range", None) or EARTH_HEIGHTS for m in models]
    lo, hi = max(r[0] for r in ranges), min(r[1] for r in ranges)
    if hi <= lo:
        raise InputError(
            f"the images' orientations share no valid height range ({ranges}): they cannot be matched together"
        )
    return float(lo), float(hi)


def windows(size, count=WINDOWS, side=WINDOW):
    """Boxes (x0, y0, x1, y1) of up to count x count windows of about `side` px spread evenly over an image of
    `size` (cols, rows) px: along a side of at most count x side px they cover it in equal parts, along a
    longer one they are `side` px wide with gaps between them."""

    def spans(n):
        if n <= count * side:
            edges = np.linspace(0, n, max(1, -(-n // side)) + 1).round().astype(int)
            return list(zip(edges[:-1], edges[1:]))
        return [(a, a + side) for a in np.linspace(0, n - side, count).round().astype(int)]

    cols, rows = (int(v) for v in size)
    return [(int(x0), int(y0), int(x1), int(y1)) for y0, y1 in spans(rows) for x0, x1 in spans(cols)]


def robust_range(heights, searched):
    """(h_min, h_max, median, kept, rejected) of matched heights (module docstring, step 4)."""
    h = np.asarray(heights, float)
    h = h[np.isfinite(h)]
    if h.size < MIN_POINTS:
        return None
    med = float(np.median(h))
    spread = max(1.4826 * float(np.median(np.abs(h - med))), MIN_SPREAD)
    keep = np.abs(h - med) <= OUTLIER_NMAD * spread
    h = h[keep]
    if h.size < MIN_POINTS:
        return None
    lo, hi = (float(v) for v in np.percentile(h, PERCENTILES))
    margin = max(MIN_MARGIN, MARGIN * (hi - lo))
    return (
        max(lo - margin, searched[0]),
        min(hi + margin, searched[1]),
        float(np.median(h)),
        int(h.size),
        int((~keep).sum()),
    )


def _window_heights(image1, image2, model1, model2, searched, box):
    """Task: the heights of the points of window `box` of image 1 matched in image 2 (steps 2 and 3)."""
    seeds = automatic_seeds(ImagePair(image1, image2, model1, model2), GrowParams(), searched, box=box, cell=CELL)
    if not len(seeds):
        return np.zeros(0)
    result = intersection.intersect_measured(
        [model1, model2], [seeds["x1"], seeds["x2"]], [seeds["y1"], seeds["y2"]], h0=0.5 * (searched[0] + searched[1])
    )
    return result.h[result.ok]


def search_heights(images, models, names=None, feedback=None, execution=None):
    """The terrain height range of a block of `images` (paths or Image) with sensor `models` (module
    docstring), the windows on `execution` (default Execution()): a HeightSearch. Raises InputError where it
    cannot be found, ExecutionError, CancelledError."""
    if len(images) < 2:
        raise InputError("the terrain height cannot be found from one image: give a DEM or a mean height")
    names = names or [f"image {k + 1}" for k in range(len(images))]
    searched = validity_range(models)
    images = [as_image(image) for image in images]
    tasks = [
        (images[0], images[k], models[0], models[k], searched, box)
        for k in range(1, len(images))
        for box in windows(models[0].size)
    ]
    heights = run_tasks(_window_heights, tasks, execution, feedback, "the height search")
    found = robust_range(np.concatenate(heights), searched)
    if found is None:
        count = int(sum(len(h) for h in heights))
        raise InputError(
            f"the terrain height could not be found: {count} point(s) of {names[0]} matched in "
            f"{', '.join(names[1:])} over the orientation's heights {searched[0]:.0f} to "
            f"{searched[1]:.0f} m (at least {MIN_POINTS} needed: do the images overlap, have texture, "
            "and is their orientation within a few pixels?); give a DEM or a mean height"
        )
    lo, hi, med, kept, rejected = found
    return HeightSearch((lo, hi), med, kept, rejected, searched)
