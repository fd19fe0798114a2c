"""Screening of the control points for gross errors, before the adjustment.

A parameter set flexible enough fits a control point that is hundreds of metres off: cubic look-angle
polynomials bend the images to it, its residuals become small, its redundancy numbers near 0, and
data snooping no longer sees it. The screen looks at the control points before anything is adjusted,
with the supplied orientation, whose error over one image is nearly a shift (an attitude or position
bias; within one scene a drift adds far less):

- each control measurement's misclosure d = projected - measured (px), its point's ground
  coordinates projected with the image's supplied model;
- per image the shift the control points agree on, the median of d, and the robust scale of what is
  left, e = d - median: s = 1.4826 median |e| (the MAD, per col and row), at least the measurement's
  a priori sigma combined with the point's largest ground sigma in pixels;
- a measurement with |e| > SCREEN_THRESHOLD s in col or row is a gross error. Only images with at
  least MIN_POINTS control measurements are screened: of two points that disagree, a median cannot
  tell which one is wrong.

A point off in every screened image, two at least, has wrong ground coordinates (or all its
measurements are wrong: `ground_points`); that is what the adjustment cannot see once a flexible
parameter set fits it. A point off in some images only has wrong measurements there: the other images
and its ground coordinates hold it, and the adjustment's data snooping flags them (bundle.py), as it
does everything smaller than SCREEN_THRESHOLD s. The offsets are given in pixels and in metres on the
ground (the image's pixel size at the point)."""

from dataclasses import dataclass, field

import numpy as np

from ..geodesy import metres_per_degree
from .bundle import CRITICAL_W
from .observations import Observations

#: control measurements an image needs to be screened
MIN_POINTS = 3
#: |e| / s above this is a gross error: twice the data snooping's critical value, as the MAD of a few
#: points can fall well below the true scale; a screen for gross errors, not a test
SCREEN_THRESHOLD = 2.0 * CRITICAL_W


@dataclass
class Suspect:
    """A control measurement the screen finds grossly off."""

    point: int  # index in the observations' points
    image_id: int
    offset_px: float  # |e| (px)
    offset_m: float  # e on the ground (m)
    ratio: float  # the larger of |e_col| / s_col and |e_row| / s_row


@dataclass
class Screening:
    """Result of `screen_control_points`."""

    suspects: list = field(default_factory=list)  # Suspects
    screened: dict = field(default_factory=dict)  # {point index: images its measurements were screened in}

    def ground_points(self) -> set:
        """Indices of the points suspect in every image they were screened in, two at least: their ground
        coordinates (or all their measurements) are wrong."""
        count = {}
        for s in self.suspects:
            count[s.point] = count.get(s.point, 0) + 1
        return {p for p, n in count.items() if n == self.screened[p] >= 2}


def _pixel_size(model, col, row, h):
    """(cols, 2) ground metres per pixel along col and along row at the image points (col, row, h)."""
    out = []
    lon, lat = model.image_to_ground(col, row, h)
    e_deg, n_deg = metres_per_degree(lat, h)
    for dc, dr in ((1.0, 0.0), (0.0, 1.0)):
        lon1, lat1 = model.image_to_ground(col + dc, row + dr, h)
        out.append(np.hypot((lon1 - lon) * e_deg, (lat1 - lat) * n_deg))
    return np.column_stack(out)


def screen_control_points(models: dict, observations: Observations) -> Screening:
    """The Suspects among the control measurements of `observations` (module docstring); models:
    {image id: sensor model}, the supplied orientation. Measurements whose point does not project
    into its image are suspects with an infinite offset."""
    p, m = observations.points, observations.measurements
    control = p["role"] == "control"
    candidates = control[m["point"]] & np.isin(m["image_id"], list(models))
    ground_sigma = np.fmax(np.fmax(p["sigma_e"], p["sigma_n"]), p["sigma_h"])
    out = Screening()
    for i in np.unique(m["image_id"][candidates]):
        k = np.flatnonzero(candidates & (m["image_id"] == i))
        if k.size < MIN_POINTS:
            continue
        pt = m["point"][k]
        for q in pt:
            out.screened[int(q)] = out.screened.get(int(q), 0) + 1
        col, row = models[i].ground_to_image(p["lon"][pt], p["lat"][pt], p["h"][pt])
        d = np.column_stack([col - m["col"][k], row - m["row"][k]])
        finite = np.isfinite(d).all(axis=1)
        for j in np.flatnonzero(~finite):
            out.suspects.append(Suspect(int(pt[j]), int(i), np.inf, np.inf, np.inf))
        if finite.sum() < MIN_POINTS:
            continue
        k, pt, d = k[finite], pt[finite], d[finite]
        e = d - np.median(d, axis=0)
        size = _pixel_size(models[i], m["col"][k], m["row"][k], p["h"][pt])
        floor = np.hypot(m["sigma"][k], ground_sigma[pt] / size.min(axis=1))
        scale = np.maximum(floor[:, None], 1.4826 * np.median(np.abs(e), axis=0)[None, :])
        ratio = np.max(np.abs(e) / scale, axis=1)
        for j in np.flatnonzero(ratio > SCREEN_THRESHOLD):
            out.suspects.append(
                Suspect(int(pt[j]), int(i), float(np.hypot(*e[j])), float(np.hypot(*(e[j] * size[j]))), float(ratio[j]))
            )
    return out


def describe(screening: Screening, observations: Observations, names: dict, points=None) -> str:
    """The suspects (of `points`, default all) in words, one clause per point: whether its ground
    coordinates or some of its measurements look wrong, and by how much (names: {image id: image name})."""
    p = observations.points
    ground = screening.ground_points()
    parts = []
    for point in dict.fromkeys(s.point for s in screening.suspects if points is None or s.point in points):
        mine = [s for s in screening.suspects if s.point == point]
        offsets = ", ".join(
            f"{names.get(s.image_id, s.image_id)} {s.offset_px:.1f} px ({s.offset_m:.0f} m)" for s in mine
        )
        what = (
            "its ground coordinates (or all its measurements) look wrong"
            if point in ground
            else "its measurement(s) there look wrong"
        )
        parts.append(f"{p['name'][point]}: {offsets} away from where the other control points put it; {what}")
    return "; ".join(parts)


def without(observations: Observations, points) -> Observations:
    """`observations` without the points of index `points` and their measurements."""
    return observations.subset(~np.isin(np.arange(len(observations.points)), list(points)))
