"""Forward-backward consistency of matched points (acceptance of the dense matching).

A pair record says: the template of image 1 at (x1, y1) matches image 2 at (x2, y2) under the
affine A = [[a1, a2], [a4, a5]]. Matching back takes the template of image 2 at (x2, y2) and
matches it into image 1 by least squares, starting from the original (x1, y1) with the inverse
affine A^-1 (region_growing.transfer_points with the roles of the images swapped and a guide made
of the records themselves, inverted). The forward-backward difference is the distance between the
back-matched image-1 position and the original one, in px of image 1. For a correct match it is
the combined noise of two LSM estimates on (mostly) the same pixels, a few hundredths of a pixel;
a wrong match (repetitive texture, occlusion, a blunder that passed the criteria) gives a
difference of the order of its error, since the image-2 template at a wrong x2 shows another
ground patch.

The back-match is accepted as a measurement when LSM converged inside both images (status ok:
finite position, iterations < maximum); the forward acceptance criteria (rho, ellipse, shift) are
NOT applied to it, so that large differences are reported rather than censored (the shift from
the initial value IS the difference when starting from the original position). Records without a
usable affine (NaN or singular) start from the sensor models' local affine of image 2 -> image 1.
"""

import dataclasses
import math

import numpy as np

from ..errors import InputError
from ..height_range import HeightRange
from .pair_geometry import ImagePair, local_affine
from .params import GrowParams
from .records import PAIR_DTYPE
from .region_growing import transfer_points

#: px searched around the start in image 1 beyond the template (window margin of the back-match)
SEARCH = 5.0


def invert_affine(a1, a2, a4, a5):
    """Elementwise inverse of [[a1, a2], [a4, a5]] -> (b1, b2, b4, b5); NaN where singular."""
    a1, a2, a4, a5 = (np.asarray(v, float) for v in (a1, a2, a4, a5))
    det = a1 * a5 - a2 * a4
    with np.errstate(invalid="ignore", divide="ignore"):
        good = np.isfinite(det) & (np.abs(det) > 1e-6)
        d = np.where(good, det, np.nan)
        return a5 / d, -a2 / d, -a4 / d, a1 / d


def back_guide(records, model1=None, model2=None, height=None):
    """The records seen from image 2: PAIR_DTYPE with (x1, y1) <-> (x2, y2) swapped and the inverse
    affine; where a record has no usable affine, the models' local affine image 2 -> image 1 at
    `height` (needs model1, model2)."""
    records = np.asarray(records, PAIR_DTYPE)
    guide = np.zeros(len(records), PAIR_DTYPE)
    guide["x1"], guide["y1"] = records["x2"], records["y2"]
    guide["x2"], guide["y2"] = records["x1"], records["y1"]
    b = np.column_stack(invert_affine(records["a1"], records["a2"], records["a4"], records["a5"]))
    missing = ~np.isfinite(b).all(axis=1)
    if missing.any():
        if model1 is None or model2 is None or height is None:
            raise InputError("records without an affine need the sensor models and a height")
        _, _, *aff = local_affine(model2, model1, records["x2"][missing], records["y2"][missing], height)
        b[missing] = np.column_stack(aff)
    guide["a1"], guide["a2"], guide["a4"], guide["a5"] = b.T
    guide["rho"] = records["rho"]
    guide["r0"], guide["r1"] = 0.0, 1.0
    guide["seed"] = np.arange(len(records))
    return guide


def forward_backward(
    pair: ImagePair,
    records,
    params=None,
    height_range=None,
    start_offset=(0.0, 0.0),
    return_records=False,
):
    """Forward-backward differences (px of image 1) of pair records matched image 1 -> image 2.

    The image-2 template at each record's (x2, y2) is least-squares matched back into image 1 from
    the record's (x1, y1) + `start_offset` with the inverse affine; the difference is the distance
    of the back-matched position from (x1, y1). NaN where the back-match failed (window leaves an
    image, singular, not converged) or the record has no image-2 position. With `return_records`,
    also the back-match PAIR_DTYPE records (x1, y1 = the image-2 template, x2, y2 = image 1)."""
    image1, image2, model1, model2 = pair
    params = (params or GrowParams()).check()
    records = np.asarray(records, PAIR_DTYPE).ravel()
    n = len(records)
    diff = np.full(n, np.nan)
    back = np.zeros(n, PAIR_DTYPE)
    back["x2"] = back["y2"] = np.nan
    usable = np.flatnonzero(
        np.isfinite(records["x1"])
        & np.isfinite(records["y1"])
        & np.isfinite(records["x2"])
        & np.isfinite(records["y2"])
    )
    if len(usable):
        rec = records[usable]
        hr = HeightRange.resolve(height_range, model1).bounds
        guide = back_guide(rec, model1, model2, 0.5 * (hr[0] + hr[1]))
        guide["x2"] += float(start_offset[0])
        guide["y2"] += float(start_offset[1])
        # max_shift only sizes the image-1 window here (acceptance is not applied, see module doc)
        wide = dataclasses.replace(params, max_shift=max(params.max_shift, SEARCH + math.hypot(*start_offset)))
        out, _ = transfer_points(ImagePair(image2, image1, model2, model1), rec["x2"], rec["y2"], wide, hr, guide=guide)
        out = np.asarray(out, PAIR_DTYPE)
        good = np.isfinite(out["x2"]) & np.isfinite(out["y2"]) & (out["iterations"] < params.max_iterations)
        d = np.hypot(out["x2"] - rec["x1"], out["y2"] - rec["y1"])
        diff[usable] = np.where(good, d, np.nan)
        back[usable] = out
    return (diff, back) if return_records else diff


def fb_summary(diff, threshold=1.0):
    """Summary of forward-backward differences: counts, RMS, median, 95th percentile and max of
    the back-matched ones, and the share (of back-matched) above `threshold` px."""
    diff = np.asarray(diff, float)
    ok = diff[np.isfinite(diff)]
    s = {"points": int(diff.size), "back_matched": int(ok.size), "failed": int(diff.size - ok.size)}
    if ok.size:
        s.update(
            rms=float(np.sqrt(np.mean(ok**2))),
            median=float(np.median(ok)),
            p95=float(np.percentile(ok, 95)),
            max=float(ok.max()),
            over=float(np.mean(ok > threshold)),
        )
    else:
        s.update(rms=math.nan, median=math.nan, p95=math.nan, max=math.nan, over=math.nan)
    s["threshold"] = float(threshold)
    return s


def format_fb(label, s):
    """One log line of an fb_summary."""
    return (
        f"{label}: {s['back_matched']} of {s['points']} back-matched, RMS {s['rms']:.3f} px, "
        f"median {s['median']:.3f}, p95 {s['p95']:.3f}, max {s['max']:.2f}, "
        f"{100 * s['over']:.2f} % > {s['threshold']:g} px"
    )


def observation_pairs(points, image_id1, image_id2, which=None):
    """PAIR_DTYPE records (no affine: NaN, so forward_backward uses the models') of the points of a
    MultiPoints observed in both images, image `image_id1` as the template: x1, y1 from its
    observations, x2, y2 from image `image_id2`'s; `which` optionally selects points (boolean mask
    over points.points, e.g. group == 3). `seed` holds the point id."""
    obs = points.observations
    ids = points.points["id"] if which is None else points.points["id"][np.asarray(which, bool)]
    o1 = obs[(obs["image_id"] == image_id1) & np.isin(obs["point_id"], ids)]
    o2 = obs[(obs["image_id"] == image_id2) & np.isin(obs["point_id"], ids)]
    common, i1, i2 = np.intersect1d(o1["point_id"], o2["point_id"], return_indices=True)
    rec = np.zeros(len(common), PAIR_DTYPE)
    rec["x1"], rec["y1"] = o1["col"][i1], o1["row"][i1]
    rec["x2"], rec["y2"] = o2["col"][i2], o2["row"][i2]
    rec["rho"] = o2["rho"][i2]
    for k in ("a1", "a2", "a4", "a5", "r0", "r1"):
        rec[k] = np.nan
    rec["seed"] = common
    return rec
