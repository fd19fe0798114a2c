"""Are imported control/check points where the block's images are, and where their measurements say? A check
at import, so that a point whose coordinates went wrong (lon/lat swapped, degrees given as projected x/y, a
point typed 10 degrees off, another CRS, a height 3000 m off) or whose measurement is another point's is named
when it enters, not found later as an adjustment that does not converge.

A point is plausible when
- its height lies within height_range.PLAUSIBLE_HEIGHTS;
- its ground position lies within MARGIN_M of the footprint of at least one block image, the footprint
  being the image border projected with the block's (supplied or adjusted) sensor model at the lowest
  and at the highest height of the block's terrain height range and of the points (within the plausible
  heights). MARGIN_M is twice the largest supplied-orientation error the adjustment is built for (SPOT 1-4
  header positions, whose Lagrange offset prior is 1000 m). The footprint is used for this test, not the
  model's ground-to-image, because an RPC's rational functions are meaningless far outside their validity
  domain and may map a far point into the image; and
- its measurements agree with its coordinates within the accuracy of the orientation (the consistency test).

The consistency test. The ray of measurement j passes the point's height h at a horizontal offset o_j (m, east
and north) from the point; with the point's true position off the given one by s (horizontal) and dh (height),
    o_j = s - d_j dh + e_j,
d_j being the ray's horizontal drift per metre of height and e_j the error of the orientation and of the
measurement there. A priori e_j has a standard deviation per axis of
    sigma_j^2 = sigma_loc^2 + (sigma_px gsd)^2,
sigma_loc the image model's stated location accuracy (SensorModel.location_sigma: SPOT 5 50 m, SPOT 1-4 1000 m,
RPC 25 m), sigma_px the measurement's a priori sigma and gsd the image's ground pixel size. If the coordinates
are right (s = 0, dh = 0), T = sum_j |o_j|^2 / sigma_j^2 follows a chi-square distribution of 2 m degrees of
freedom (m measurements), and the point is implausible where T exceeds its 1 - FALSE_ALARM quantile: a
true point is refused once in a million, whatever the data. (The errors of images of one pass are correlated,
which the test takes as independent: a shift common to m images weighs m times; the small FALSE_ALARM leaves
room for it, a common shift of 3 sigma with three images passes.) A 3000 m height error moves a ray viewing
20 degrees off nadir by 1100 m, twenty times SPOT 5's 50 m.

For a point that fails, the message says why: with two or more measurements whose rays cross at an angle,
where they meet (the least-squares intersection (s, dh) in the linear model above: a height or a position off,
when the rays meet among themselves) or which ray misses the others (a measurement of another point); with one,
how far its measurement lies from where the coordinates project. For a point off the footprints, `diagnose` says
what its numbers look like: lon/lat swapped (the swapped position is inside a footprint), degrees given as
projected x/y (x, y within +-180, +-90 in a projected CRS), or just how far it lies from the images."""

import numpy as np
from scipy.special import chdtri

from ..geodesy import metres_per_degree
from ..height_range import PLAUSIBLE_HEIGHTS, outside_plausible

MARGIN_M = 2000.0
#: the consistency test's rate of refusing a true point
FALSE_ALARM = 1e-6
#: a 2-D offset beyond this many sigmas is out of line at the FALSE_ALARM rate (chi-square of 2 degrees)
SIGMAS_2D = float(np.sqrt(chdtri(2, FALSE_ALARM)))
#: a height beyond this many sigmas likewise (chi-square of 1 degree)
SIGMAS_1D = float(np.sqrt(chdtri(1, FALSE_ALARM)))
#: half the height step (m) over which a ray's horizontal drift per metre of height is measured
RAY_STEP = 50.0
#: rays meet at one place where their normal matrix is better conditioned than this (else they are parallel)
MAX_CONDITION = 1e8


def _local(lon, lat, lon0, lat0):
    """Metres east/north of (lon0, lat0), equirectangular (the footprints span tens of km)."""
    east, north = metres_per_degree(lat0)
    return (np.asarray(lon) - lon0) * east, (np.asarray(lat) - lat0) * north


def distance_to_polygon(x, y, ring):
    """Distance (same units) of points (x, y) from the closed polygon `ring` (n, 2): 0 inside."""
    x, y = np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float))
    a, b = ring[:-1], ring[1:]
    crosses = (a[:, 1][:, None] > y) != (b[:, 1][:, None] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = a[:, 0][:, None] + (y - a[:, 1][:, None]) * (b[:, 0] - a[:, 0])[:, None] / (b[:, 1] - a[:, 1])[:, None]
    inside = np.logical_xor.reduce(crosses & (x < at), axis=0)
    d = b - a
    length2 = np.maximum((d**2).sum(axis=1), 1e-300)[:, None]
    t = np.clip(
        ((x - a[:, 0][:, None]) * d[:, 0][:, None] + (y - a[:, 1][:, None]) * d[:, 1][:, None]) / length2, 0.0, 1.0
    )
    dist = np.hypot(a[:, 0][:, None] + t * d[:, 0][:, None] - x, a[:, 1][:, None] + t * d[:, 1][:, None] - y).min(
        axis=0
    )
    return np.where(inside, 0.0, dist)


class Footprints:
    """The block images' footprints at two heights (module docstring), in metres around the block's centre.
    `models`: {image id: sensor model}; `names`: {image id: name}; `heights`: the block's terrain height
    range and the points' heights."""

    def __init__(self, models, names, heights):
        self.models, self.names = models, names
        heights = np.clip(np.asarray([h for h in heights if np.isfinite(h)], float), *PLAUSIBLE_HEIGHTS)
        self.heights = (float(heights.min()), float(heights.max())) if heights.size else (0.0, 0.0)
        rings = {i: [m.footprint(h=h) for h in self.heights] for i, m in models.items()}
        everything = np.vstack([r for rs in rings.values() for r in rs])
        self.lon0, self.lat0 = float(everything[:, 0].mean()), float(everything[:, 1].mean())
        self.rings = {
            i: [np.column_stack(_local(r[:, 0], r[:, 1], self.lon0, self.lat0)) for r in rs] for i, rs in rings.items()
        }
        self.gsd = {}
        for i, m in models.items():
            x, y = self.rings[i][0][:-1].T
            area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
            self.gsd[i] = float(np.sqrt(area / float(m.size[0] * m.size[1])))

    def distance(self, lon, lat):
        """Distance (m) of each point from the nearest footprint."""
        x, y = _local(lon, lat, self.lon0, self.lat0)
        best = np.full(np.shape(x), np.inf)
        for rings in self.rings.values():
            for ring in rings:
                best = np.minimum(best, distance_to_polygon(x, y, ring))
        return best

    def rays(self, observations):
        """Per measurement (consistency test, module docstring): the offset o (n, 2; m east, north) from its
        point to where its ray passes the point's height, the ray's drift d (n, 2; m east, north per metre of
        height) and the a priori sigma (n,; m per axis) of o. NaN where the model gives the ray no ground
        position there (far outside an RPC's domain: the footprint test names the point) or states no accuracy."""
        p, m = observations.points, observations.measurements
        offset, drift, sigma = np.full((len(m), 2), np.nan), np.full((len(m), 2), np.nan), np.full(len(m), np.nan)
        for i, model in self.models.items():
            k = np.flatnonzero(m["image_id"] == i)
            if not len(k) or model.location_sigma is None:
                continue
            pts = p[m["point"][k]]
            east, north = metres_per_degree(pts["lat"], pts["h"])
            ground = []
            for step in (0.0, -RAY_STEP, RAY_STEP):
                with np.errstate(all="ignore"):
                    lon, lat = model.image_to_ground_or_nan(m["col"][k], m["row"][k], pts["h"] + step)
                ground.append(
                    np.column_stack(
                        [
                            ((np.asarray(lon) - pts["lon"] + 180.0) % 360.0 - 180.0) * east,
                            (np.asarray(lat) - pts["lat"]) * north,
                        ]
                    )
                )
            offset[k], drift[k] = ground[0], (ground[2] - ground[1]) / (2.0 * RAY_STEP)
            sigma[k] = np.hypot(model.location_sigma, m["sigma"][k] * self.gsd[i])
        return offset, drift, sigma


def inconsistency(name, point, rows, rays, observations, names):
    """One line on why the measurements `rows` (indices, their rays without NaN) of the point `point` (a
    POINT_DTYPE row named `name`) disagree with its coordinates, None where they agree (the consistency test and
    its diagnosis, module docstring). `rays`: Footprints.rays of `observations`; `names`: {image id: name}."""
    offset, drift, sigma = (v[rows] for v in rays)
    w = 1.0 / sigma**2
    if np.sum(w * (offset**2).sum(axis=1)) <= chdtri(2 * len(rows), FALSE_ALARM):
        return None
    m = observations.measurements[rows]

    def where(j):
        return f"in {names[int(m['image_id'][j])]} at ({m['col'][j]:.1f}, {m['row'][j]:.1f})"

    if len(rows) >= 2:  # the rays' intersection: o_j = s - d_j dh, in least squares
        a = np.zeros((2 * len(rows), 3))
        a[0::2, 0], a[1::2, 1], a[:, 2] = 1.0, 1.0, -drift.ravel()
        wv = np.repeat(w, 2)
        normal = a.T @ (wv[:, None] * a)
        if np.linalg.cond(normal) < MAX_CONDITION:
            x = np.linalg.solve(normal, a.T @ (wv * offset.ravel()))
            residual = (offset.ravel() - a @ x).reshape(-1, 2)
            misses = w * (residual**2).sum(axis=1)
            if misses.sum() > chdtri(2 * len(rows) - 3, FALSE_ALARM):
                if len(rows) == 2:
                    return (
                        f"{name}: its rays do not meet: those of its measurements {where(0)} and {where(1)} pass "
                        f"{np.hypot(*(residual[0] - residual[1])):.0f} m apart, where the orientation's accuracy "
                        f"allows about {SIGMAS_2D * np.hypot(*sigma):.0f} m: a measurement of another point, or in "
                        "another image"
                    )
                j = int(np.argmax(misses))
                return (
                    f"{name}: its rays do not meet: the one of its measurement {where(j)} passes "
                    f"{np.hypot(*residual[j]):.0f} m from where the others meet, where the orientation's accuracy "
                    f"allows about {SIGMAS_2D * sigma[j]:.0f} m: a measurement of another point, or in another "
                    "image"
                )
            covariance = np.linalg.inv(normal)
            dh, across = float(x[2]), float(np.hypot(x[0], x[1]))
            return (
                f"{name}: its measurements meet {abs(dh):.0f} m {'above' if dh > 0 else 'below'} its height "
                f"{point['h']:.1f} m and {across:.0f} m beside its position, where the orientation's accuracy "
                f"allows about {SIGMAS_1D * np.sqrt(covariance[2, 2]):.0f} m in height and "
                f"{SIGMAS_2D * np.sqrt(max(covariance[0, 0], covariance[1, 1])):.0f} m beside: its coordinates "
                "are wrong (a typo, another height datum or unit, another point's coordinates)"
            )
    j = int(np.argmax(w * (offset**2).sum(axis=1)))
    return (
        f"{name}: measured {where(j)}, {np.hypot(*offset[j]) / 1000:.1f} km from where its coordinates project, "
        f"where the orientation's accuracy allows about {SIGMAS_2D * sigma[j]:.0f} m: another point's measurement, "
        "or coordinates in another CRS"
    )


def diagnose(name, lon, lat, distance, footprints, degrees_as_projected=False):
    """One line on why the point `name` is implausible and what its numbers look like."""
    if degrees_as_projected:
        return (
            f"{name}: its x/y look like degrees, not coordinates of the projected CRS given (lies "
            f"{distance / 1000:.0f} km from the images): name the columns lon, lat, or give the geographic CRS"
        )
    if abs(lon) <= 90.0 and footprints.distance(np.array([lat]), np.array([lon]))[0] <= MARGIN_M:
        return f"{name}: lon {lon:.6f} and lat {lat:.6f} look swapped (swapped, it lies on the images)"
    return (
        f"{name}: lies {distance / 1000:.1f} km outside every image footprint (lon {lon:.6f}, lat {lat:.6f}): "
        "check its coordinates and their CRS"
    )


def implausible_points(observations, footprints, degrees_as_projected=None):
    """Lines naming the points of `observations` that fail the tests (module docstring), [] when all pass.
    `degrees_as_projected`: bool per point, its x/y were within +-180, +-90 in a projected CRS."""
    p, m = observations.points, observations.measurements
    low, high = PLAUSIBLE_HEIGHTS
    lines = [
        f"{p['name'][k]}: its height {p['h'][k]:g} m lies outside the heights of terrain on Earth ({low:g} .. "
        f"{high:g} m): a height in another unit, or from another column"
        for k in np.flatnonzero(outside_plausible(p["h"]))
    ]
    far = footprints.distance(p["lon"], p["lat"])
    flags = np.zeros(len(p), bool) if degrees_as_projected is None else np.asarray(degrees_as_projected, bool)
    lines += [
        diagnose(p["name"][k], p["lon"][k], p["lat"][k], far[k], footprints, flags[k])
        for k in np.flatnonzero((far > MARGIN_M) & ~outside_plausible(p["h"]))
    ]
    rays = footprints.rays(observations)
    usable = np.isfinite(rays[0]).all(axis=1) & np.isfinite(rays[1]).all(axis=1) & np.isfinite(rays[2])
    for k in np.flatnonzero((far <= MARGIN_M) & ~outside_plausible(p["h"])):
        rows = np.flatnonzero((m["point"] == k) & usable)
        line = inconsistency(p["name"][k], p[k], rows, rays, observations, footprints.names) if len(rows) else None
        if line:
            lines.append(line)
    return lines
