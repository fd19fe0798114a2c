"""Are imported control/check points where the block's images are? A check at import, so that a point
whose coordinates went wrong (lon/lat swapped, degrees given as projected x/y, a point typed 10 degrees
off, another CRS) is named when it enters, not found later as an adjustment that does not converge.

A point is plausible when
- its ground position lies within MARGIN_M of the footprint of at least one block image, the footprint
  being the image border projected with the block's (supplied or adjusted) sensor model at the lowest
  and at the highest height of the block's terrain height range and of the points (within HEIGHT_LIMITS);
  and
- each of its image measurements lies within MARGIN_M (on the ground: the pixel distance times the
  image's ground sampling distance) of where its ground position projects into that image.

MARGIN_M is twice the largest supplied-orientation error the adjustment is built for (SPOT 1-4 header
positions, whose Lagrange offset prior is 1000 m): no point that an adjustment could use is refused.
The footprint is used for the first test, not the model's ground-to-image, because an RPC's rational
functions are meaningless far outside their validity domain and may map a far point into the image.

For a point that fails, `diagnose` says what its numbers look like: lon/lat swapped (the swapped position
is inside a footprint), degrees given as projected x/y (x, y within +-180, +-90 in a projected CRS), or
just how far it lies from the images."""
import numpy as np

from ..errors import PushbroomError
from ..geodesy import metres_per_degree

MARGIN_M = 2000.0
#: heights (m) outside which no terrain lies: a point's height beyond them does not widen the test
HEIGHT_LIMITS = (-500.0, 9000.0)


def _local(lon, lat, lon0, lat0):
    """Metres east/north of (lon0, lat0), equirectangular (the footprints span tens of km)."""
    east, north = metres_per_degree(lat0)
    return (np.asarray(lon) - lon0) * east, (np.asarray(lat) - lat0) * north


def distance_to_polygon(x, y, ring):
    """Distance (same units) of points (x, y) from the closed polygon `ring` (n, 2): 0 inside."""
    x, y = np.atleast_1d(np.asarray(x, float)), np.atleast_1d(np.asarray(y, float))
    a, b = ring[:-1], ring[1:]
    crosses = ((a[:, 1][:, None] > y) != (b[:, 1][:, None] > y))
    with np.errstate(divide="ignore", invalid="ignore"):
        at = a[:, 0][:, None] + (y - a[:, 1][:, None]) * (b[:, 0] - a[:, 0])[:, None] / (b[:, 1] - a[:, 1])[:, None]
    inside = np.logical_xor.reduce(crosses & (x < at), axis=0)
    d = b - a
    length2 = np.maximum((d ** 2).sum(axis=1), 1e-300)[:, None]
    t = np.clip(((x - a[:, 0][:, None]) * d[:, 0][:, None] + (y - a[:, 1][:, None]) * d[:, 1][:, None]) / length2,
                0.0, 1.0)
    dist = np.hypot(a[:, 0][:, None] + t * d[:, 0][:, None] - x,
                    a[:, 1][:, None] + t * d[:, 1][:, None] - y).min(axis=0)
    return np.where(inside, 0.0, dist)


class Footprints:
    """The block images' footprints at two heights (module docstring), in metres around the block's centre.
    `models`: {image id: sensor model}; `names`: {image id: name}; `heights`: the block's terrain height
    range and the points' heights."""

    def __init__(self, models, names, heights):
        self.models, self.names = models, names
        heights = np.clip(np.asarray([h for h in heights if np.isfinite(h)], float), *HEIGHT_LIMITS)
        self.heights = (float(heights.min()), float(heights.max())) if heights.size else (0.0, 0.0)
        rings = {i: [m.footprint(h=h) for h in self.heights] for i, m in models.items()}
        everything = np.vstack([r for rs in rings.values() for r in rs])
        self.lon0, self.lat0 = float(everything[:, 0].mean()), float(everything[:, 1].mean())
        self.rings = {i: [np.column_stack(_local(r[:, 0], r[:, 1], self.lon0, self.lat0)) for r in rs]
                      for i, rs in rings.items()}
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

    def measurement_offsets(self, observations):
        """Ground distance (m) between each image measurement and the projection of its point's
        coordinates into that image (NaN where the projection fails)."""
        p, m = observations.points, observations.measurements
        out = np.full(len(m), np.nan)
        for i, model in self.models.items():
            k = np.flatnonzero(m["image_id"] == i)
            if not len(k):
                continue
            pts = p[m["point"][k]]
            with np.errstate(all="ignore"):
                try:
                    col, row = model.ground_to_image(pts["lon"], pts["lat"], pts["h"])
                except PushbroomError:  # far outside a model's domain: the footprint test names the point
                    continue
            out[k] = np.hypot(np.asarray(col) - m["col"][k], np.asarray(row) - m["row"][k]) * self.gsd[i]
        return out


def diagnose(name, lon, lat, distance, footprints, degrees_as_projected=False):
    """One line on why the point `name` is implausible and what its numbers look like."""
    if degrees_as_projected:
        return (f"{name}: its x/y look like degrees, not coordinates of the projected CRS given (lies "
                f"{distance / 1000:.0f} km from the images): name the columns lon, lat, or give the geographic CRS")
    if abs(lon) <= 90.0 and footprints.distance(np.array([lat]), np.array([lon]))[0] <= MARGIN_M:
        return f"{name}: lon {lon:.6f} and lat {lat:.6f} look swapped (swapped, it lies on the images)"
    return (f"{name}: lies {distance / 1000:.1f} km outside every image footprint (lon {lon:.6f}, lat {lat:.6f}): "
            "check its coordinates and their CRS")


def implausible_points(observations, footprints, degrees_as_projected=None):
    """Lines naming the points of `observations` that fail the test (module docstring), [] when all pass.
    `degrees_as_projected`: bool per point, its x/y were within +-180, +-90 in a projected CRS."""
    p, m = observations.points, observations.measurements
    far = footprints.distance(p["lon"], p["lat"])
    flags = np.zeros(len(p), bool) if degrees_as_projected is None else np.asarray(degrees_as_projected, bool)
    lines = [diagnose(p["name"][k], p["lon"][k], p["lat"][k], far[k], footprints, flags[k])
             for k in np.flatnonzero(far > MARGIN_M)]
    offsets = footprints.measurement_offsets(observations)
    for j in np.flatnonzero((offsets > MARGIN_M) & (far[m["point"]] <= MARGIN_M)):
        lines.append(f"{p['name'][m['point'][j]]}: measured in {footprints.names[int(m['image_id'][j])]} at "
                     f"({m['col'][j]:.1f}, {m['row'][j]:.1f}), {offsets[j] / 1000:.1f} km from where its coordinates "
                     "project: another point's measurement, or coordinates in another CRS?")
    return lines
