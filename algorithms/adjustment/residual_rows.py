"""Residuals of the last bundle adjustment per control and check point, as the rows the block stores
(block/residuals.py) for the measurement window:

- per image measurement of a control or check point the residual v = computed - measured (px; x = col,
  y = row) and the normalised residual w = v / (sigma sqrt(r)). Control points: Adjustment.residuals /
  .normalised; check points: the residuals of their forward intersection with the adjusted models
  (Kornus et al. 2006, section 3.5.1, adjustment/residual_vectors.intersection_residuals: reprojection
  of the intersected point, with the redundancy numbers of that intersection);
- per point the ground residuals (m; control: adjusted - observed, check: intersected - reference) and the
  RMS of the point's 2k image residual coordinates (residual_vectors.per_point).

Measurements the adjustment removed as blunders, points it left out and tie points have no rows."""

import numpy as np

from ..geodesy import offset_enu
from .residual_vectors import intersection_residuals, per_point


def check_residuals(models, check, observations):
    """(names, measurements, v, w, rms): the image residuals of the check points of
    bundle.check_points' dict `check`, at their intersected positions (reference + dE, dN, dH)
    reprojected with the adjusted `models`: `measurements` (MEAS_DTYPE, `point` indexing `names`)
    are their measurements in `observations`, v and w (M, 2) residuals (px) and normalised
    residuals, rms (px) per point."""
    names = [str(n) for n in check["names"]]
    chk = observations.subset(np.isin(observations.points["name"], names))
    row_of = {n: k for k, n in enumerate(names)}
    rows = np.array([row_of[n] for n in chk.points["name"].tolist()], np.int64)
    d = np.column_stack([check["dE"], check["dN"], check["dH"]]).reshape(-1, 3)[rows]
    pts, meas = chk.points, chk.measurements
    if not len(meas):
        return pts["name"], meas, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(len(pts))
    lon, lat, h = offset_enu(pts["lon"], pts["lat"], pts["h"], d)
    v, r = intersection_residuals(models, lon, lat, h, meas)
    with np.errstate(invalid="ignore", divide="ignore"):
        w = v / (meas["sigma"][:, None] * np.sqrt(np.clip(r, 1e-12, None)))
    rms, _ = per_point(meas["point"], len(pts), v, w)
    return pts["name"], meas, v, w, rms


def residual_rows(adjustment, check, observations):
    """(measurement rows, point rows) of block/residuals.py's tables: tuples in
    its MEASUREMENT_FIELDS and POINT_FIELDS order, control points first, then check points."""
    obs = adjustment.observations
    roles = obs.points["role"]
    m = obs.measurements
    rms, _ = per_point(m["point"], len(obs.points), adjustment.residuals, adjustment.normalised)
    keep = roles[m["point"]] == "control"
    meas_rows = [
        (str(obs.points["name"][k["point"]]), int(k["image_id"]), "control", *v, *w)
        for k, v, w in zip(m[keep], adjustment.residuals[keep], adjustment.normalised[keep])
    ]
    point_rows = [
        (str(obs.points["name"][p]), "control", *adjustment.ground_residuals[p], rms[p])
        for p in np.flatnonzero(roles == "control")
    ]
    names, meas, v, w, rms = check_residuals(adjustment.parameters.models, check, observations)
    meas_rows += [(str(names[k["point"]]), int(k["image_id"]), "check", *vk, *wk) for k, vk, wk in zip(meas, v, w)]
    d = {str(n): (e, nn, h) for n, e, nn, h in zip(check["names"], check["dE"], check["dN"], check["dH"])}
    point_rows += [(str(n), "check", *d[str(n)], rms[k]) for k, n in enumerate(names)]
    return meas_rows, point_rows
