"""Observations of a block adjustment: ground points and their image measurements.

`GroundPoints` (POINT_DTYPE), one row per object point: name, role ("control": ground coordinates
observed, image measurements used; "check": image measurements only used to intersect the point
after the adjustment, never in it; "tie": image measurements only), geodetic WGS 84 lon/lat
(degrees) and ellipsoidal height (m) (NaN for tie points), and the a priori standard deviations
of the ground coordinates east/north/up in metres (NaN where not observed).

`Measurements` (MEAS_DTYPE), one row per image measurement: index of its point in the points
array, block image id, col/row (GDAL convention) and the a priori standard deviation (px, the
same for col and row)."""

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..sigmas import IMAGE_SIGMA

ROLES = ("control", "check", "tie")
POINT_DTYPE = np.dtype(
    [
        ("name", "U32"),
        ("role", "U7"),
        ("lon", "f8"),
        ("lat", "f8"),
        ("h", "f8"),
        ("sigma_e", "f8"),
        ("sigma_n", "f8"),
        ("sigma_h", "f8"),
    ]
)
MEAS_DTYPE = np.dtype([("point", "i8"), ("image_id", "i8"), ("col", "f8"), ("row", "f8"), ("sigma", "f8")])


@dataclass
class Observations:
    """Points and measurements of one adjustment (see module docstring)."""

    points: np.ndarray = field(default_factory=lambda: np.zeros(0, POINT_DTYPE))
    measurements: np.ndarray = field(default_factory=lambda: np.zeros(0, MEAS_DTYPE))

    def __post_init__(self):
        self.points = np.asarray(self.points, POINT_DTYPE)
        self.measurements = np.asarray(self.measurements, MEAS_DTYPE)

    def check(self):
        """Raise InputError on inconsistent observations; returns self."""
        p, m = self.points, self.measurements
        bad_role = ~np.isin(p["role"], ROLES)
        if bad_role.any():
            raise InputError(
                f"point {p['name'][bad_role][0]!r} has role {p['role'][bad_role][0]!r}; roles are {', '.join(ROLES)}"
            )
        ground = p["role"] != "tie"
        missing = ground & ~(np.isfinite(p["lon"]) & np.isfinite(p["lat"]) & np.isfinite(p["h"]))
        if missing.any():
            raise InputError(f"{p['role'][missing][0]} point {p['name'][missing][0]!r} has no ground coordinates")
        control = p["role"] == "control"
        sig = np.column_stack([p["sigma_e"], p["sigma_n"], p["sigma_h"]])[control]
        if sig.size and not (np.isfinite(sig).all() and (sig > 0).all()):
            raise InputError("every control point needs positive ground sigmas (east, north, height)")
        if m.size and ((m["point"] < 0) | (m["point"] >= len(p))).any():
            raise InputError("an image measurement refers to a point that does not exist")
        if m.size and not (np.isfinite(m["sigma"]).all() and (m["sigma"] > 0).all()):
            raise InputError("every image measurement needs a positive sigma")
        blank = ~(np.isfinite(m["col"]) & np.isfinite(m["row"]))
        if blank.any():
            raise InputError(
                f"the measurement of point {p['name'][m['point'][blank][0]]!r} in image id "
                f"{m['image_id'][blank][0]} has no image coordinates (col, row must be numbers)"
            )
        names, counts = np.unique(p["name"], return_counts=True)
        if (counts > 1).any():
            raise InputError(f"point name {names[counts > 1][0]!r} is used twice")
        return self

    def sorted(self):
        """The same observations with the measurements ordered by point, then image id."""
        m = self.measurements
        return Observations(self.points, m[np.lexsort((m["image_id"], m["point"]))])

    def subset(self, keep):
        """The observations of the points where `keep` (bool per point) is true."""
        keep = np.asarray(keep, bool)
        new_index = np.cumsum(keep) - 1
        m = self.measurements[keep[self.measurements["point"]]].copy()
        m["point"] = new_index[m["point"]]
        return Observations(self.points[keep].copy(), m)

    def concatenate(self, other):
        """These observations followed by `other`'s (their point indices shifted)."""
        m = other.measurements.copy()
        m["point"] += len(self.points)
        return Observations(np.concatenate([self.points, other.points]), np.concatenate([self.measurements, m]))


def tie_observations(multipoints, sigma=IMAGE_SIGMA, prefix="T"):
    """Observations of matched tie points (matching.points.MultiPoints), role "tie", each
    measurement with the a priori sigma `sigma` px; names prefix + point id."""
    pts = multipoints.points
    obs = multipoints.observations
    points = np.zeros(len(pts), POINT_DTYPE)
    points["name"] = [f"{prefix}{i}" for i in pts["id"]]
    points["role"] = "tie"
    for key in ("lon", "lat", "h", "sigma_e", "sigma_n", "sigma_h"):
        points[key] = np.nan
    meas = np.zeros(len(obs), MEAS_DTYPE)
    meas["point"] = np.searchsorted(pts["id"], obs["point_id"])
    meas["image_id"], meas["col"], meas["row"], meas["sigma"] = obs["image_id"], obs["col"], obs["row"], sigma
    return Observations(points, meas)
