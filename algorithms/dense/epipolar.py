"""Epipolar resampling grids of an image pair, one per tile, from the two sensor models (rigorous SPOT
or RPC, adjusted or not).

Model. q(p, h) is the image-2 position of image-1 point p at ellipsoidal height h, b(q, h) the image-1
position of image-2 point q (pair_geometry.predict both ways). The epipolar direction of image 1 at p is
the tangent of the curve h -> b(q(p, h_m), h) through p, the image-1 trace of the ray of p's conjugate:

    e1(p) = unit(b(Q, h_m - dh) - b(Q, h_m + dh)),   Q = q(p, h_m),   dh = max((h_hi - h_lo) / 2, 100 m)

with h_m the middle of the tile's height range (h_lo, h_hi). Epipolar coordinates (u, v) of a tile:
- image 1: the rows are integral curves of e1, traced from row starts spaced along the normal n1 of e1
  at the tile's centre p_c (row v starts at p_c + v s_v n1), in steps of the grid step by the midpoint
  (second-order Runge-Kutta) rule: P(u, v) for u, v on the grid's nodes;
- image 2: Q(u, v) = q(P(u, v), h_m), the same ground point at the middle height.
An epipolar pixel is a square of g metres on the ground (s_u, s_v: image-1 px per epipolar px along e1,
n1), g the larger of the two images' mean ground sample distances at the tile's centre (the square root
of a pixel's ground area), so the finer image is sampled down to the coarser one, never the other way:
SPOT 5 HRS (10 m x 5 m) against HRG (5 m) gives g = 7.1 m. (Low-pass the finer image first:
matching.resolution.adapt_resolution.) Between the nodes, P and Q are bilinear in (u, v).

Disparity. The conjugate of image-1 epipolar point (u, v) at height h lies at image-2 epipolar point
(u + d(h), v'), d increasing with h (e1's sign is chosen so). For pushbroom images epipolar curves do
not pair exactly (Kim 2000, "The epipolar resampling of pushbroom satellite imagery"), so v' = v only
approximately. Each grid states two errors, measured at the centres of its cells and at the tile's
lowest, middle and highest heights:
- `row_error`: max |v' - v| (epipolar px), the pairing and the interpolation together;
- `interpolation_error`: max |Q(u, v) - q(P(u, v), h_m)| (image-2 px) between the nodes.
Both grow with the grid step and the tile's height range.

Conventions: image positions are GDAL's (pixel centres at half-integers); an epipolar image's array
element [i, j] is the sample at (u, v) = (u0 + j, v0 + i); node (a, b) of the grid is at
(u0 + b step, v0 + a step). A model point outside its domain is NaN, and so are the grid nodes after it.

Failures (InputError): the tile's centre has no image-2 position at the middle height (the images do not
overlap there), or the rays are parallel (less than 0.05 image-1 px of parallax over 2 dh: no stereo
base, no epipolar geometry).

Reference: M. Kim, "A note on the epipolar geometry of linear pushbroom imagery", PE&RS 66(8), 2000;
the grid idea follows CNES shareloc's stereo-rectification grids (traced along local epipolar
directions), here per tile and with the pairing error measured."""

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError
from ..geodesy import geodetic_to_ecef
from ..matching.pair_geometry import predict
from ..sensors.base import SensorModel

#: an image direction (dx, dy) px
Direction = tuple[float, float] | np.ndarray
MIN_PARALLAX_PX = 0.05  # image-1 px over 2 dh below which the rays count as parallel
MIN_HALF_RANGE_M = 100.0  # dh: at least this, so that a flat tile still has a direction


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.hypot(v[..., 0], v[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n[..., None]


def pixel_gsd(
    model: SensorModel, x: float, y: float, h: float, d1: Direction, d2: Direction
) -> tuple[float, float, float]:
    """Ground metres per px along image directions d1, d2 at (x, y, h), and the pixel's mean GSD
    (the square root of its ground area)."""
    xs = np.array([x, x + d1[0], x + d2[0]])
    ys = np.array([y, y + d1[1], y + d2[1]])
    lon, lat = model.image_to_ground(xs, ys, np.full(3, h))
    e = geodetic_to_ecef(np.asarray(lon, float), np.asarray(lat, float), np.full(3, h))
    a, b = e[1] - e[0], e[2] - e[0]
    area = np.linalg.norm(np.cross(a, b)) / abs(d1[0] * d2[1] - d1[1] * d2[0])
    return float(np.linalg.norm(a)), float(np.linalg.norm(b)), float(np.sqrt(area))


@dataclass
class EpipolarGrid:
    """The epipolar resampling grid of one tile: node positions in both images and the errors it states.

    p, q: (rows, cols, 2) image-1 and image-2 positions (x, y) of the nodes; u0, v0: epipolar
    coordinates of node (0, 0); step: epipolar px between nodes; heights: (h_lo, h_m, h_hi);
    gsd: the epipolar pixel's ground size (m); row_error, interpolation_error: see the module."""

    p: np.ndarray
    q: np.ndarray
    u0: float
    v0: float
    step: int
    heights: tuple
    gsd: float
    row_error: float = np.nan
    interpolation_error: float = np.nan

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the epipolar images the grid spans."""
        return ((self.p.shape[0] - 1) * self.step + 1, (self.p.shape[1] - 1) * self.step + 1)

    def _interp(self, nodes: np.ndarray, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bilinear (x, y) of `nodes` at epipolar (u, v) (arrays), and its derivatives by u and by v
        (extrapolated by the border cells outside the grid)."""
        fb = (np.asarray(u, float) - self.u0) / self.step
        fa = (np.asarray(v, float) - self.v0) / self.step
        with np.errstate(invalid="ignore"):  # NaN (u, v) give NaN, through tb, ta
            b = np.clip(np.nan_to_num(np.floor(fb)), 0, nodes.shape[1] - 2).astype(int)
            a = np.clip(np.nan_to_num(np.floor(fa)), 0, nodes.shape[0] - 2).astype(int)
        tb, ta = (fb - b)[..., None], (fa - a)[..., None]
        n00, n01, n10, n11 = nodes[a, b], nodes[a, b + 1], nodes[a + 1, b], nodes[a + 1, b + 1]
        top, bottom = n00 + tb * (n01 - n00), n10 + tb * (n11 - n10)
        du = ((1 - ta) * (n01 - n00) + ta * (n11 - n10)) / self.step
        dv = (bottom - top) / self.step
        return top + ta * (bottom - top), du, dv

    def image1(self, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Image-1 (x, y) of epipolar (u, v)."""
        xy = self._interp(self.p, u, v)[0]
        return xy[..., 0], xy[..., 1]

    def image2(self, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Image-2 (x, y) of epipolar (u, v)."""
        xy = self._interp(self.q, u, v)[0]
        return xy[..., 0], xy[..., 1]

    def along(self, dx: ArrayLike, dy: ArrayLike) -> np.ndarray:
        """The components (px) of image-2 moves (dx, dy) (px) along the epipolar line: the direction of the image-2
        nodes' least-squares affine in u (the defined nodes'), which the grid follows within its interpolation error
        over a tile."""
        good = np.isfinite(self.q).all(axis=-1)
        v, u = (np.nonzero(good)[k] * self.step for k in (0, 1))
        design = np.column_stack([u, v, np.ones(u.size)])
        direction = np.linalg.lstsq(design, self.q[good], rcond=None)[0][0]  # d(x, y) / du
        direction = direction / np.hypot(*direction)
        return direction[0] * np.asarray(dx, float) + direction[1] * np.asarray(dy, float)

    def epipolar1(self, x1: ArrayLike, y1: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Epipolar (u, v) of image-1 points (x1, y1) (see epipolar2)."""
        return self._invert(self.p, x1, y1)

    def epipolar2(self, x2: ArrayLike, y2: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Epipolar (u, v) of image-2 points (x2, y2): the bilinear grid inverted by Newton's method
        from the affine fit of all nodes; NaN where it does not converge to 1e-3 px."""
        return self._invert(self.q, x2, y2)

    def _invert(
        self, nodes: np.ndarray, x: ArrayLike, y: ArrayLike, iterations: int = 20, tol: float = 1e-6
    ) -> tuple[np.ndarray, np.ndarray]:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        target = np.stack([x, y], axis=-1)
        good = np.isfinite(nodes).all(axis=-1)
        vv, uu = np.nonzero(good)
        a = np.column_stack([nodes[good], np.ones(good.sum())])
        coef = np.linalg.lstsq(a, np.column_stack([self.u0 + uu * self.step, self.v0 + vv * self.step]), rcond=None)[0]
        uv = np.concatenate([target, np.ones(target.shape[:-1] + (1,))], axis=-1) @ coef
        u, v = uv[..., 0], uv[..., 1]
        for _ in range(iterations):
            xy, du, dv = self._interp(nodes, u, v)
            r = target - xy
            det = du[..., 0] * dv[..., 1] - du[..., 1] * dv[..., 0]
            with np.errstate(invalid="ignore", divide="ignore"):
                su = (r[..., 0] * dv[..., 1] - r[..., 1] * dv[..., 0]) / det
                sv = (du[..., 0] * r[..., 1] - du[..., 1] * r[..., 0]) / det
            u, v = u + su, v + sv
            if not np.any(np.abs(su) + np.abs(sv) > tol):
                break
        xy = self._interp(nodes, u, v)[0]
        off = np.hypot(*(target - xy).transpose(-1, *range(target.ndim - 1)))
        bad = ~(off < 1e-3)
        return np.where(bad, np.nan, u), np.where(bad, np.nan, v)


def _direction(
    model1: SensorModel, model2: SensorModel, p: np.ndarray, h_m: float, dh: float
) -> tuple[np.ndarray, np.ndarray]:
    """e1 at image-1 points p (n, 2): unit(b(Q, h_m - dh) - b(Q, h_m + dh)), and the parallax length."""
    x2, y2 = predict(model1, model2, p[:, 0], p[:, 1], np.full(len(p), h_m))
    lo = np.column_stack(predict(model2, model1, x2, y2, np.full(len(p), h_m - dh)))
    hi = np.column_stack(predict(model2, model1, x2, y2, np.full(len(p), h_m + dh)))
    d = lo - hi
    return _unit(d), np.hypot(d[:, 0], d[:, 1])


def _trace(
    model1: SensorModel,
    model2: SensorModel,
    starts: np.ndarray,
    e_ref: np.ndarray,
    n_steps: int,
    length: float,
    h_m: float,
    dh: float,
) -> np.ndarray:
    """Rows (len(starts), n_steps + 1, 2) traced from `starts` along e1 in steps of `length` image-1 px
    (negative: backwards) by the midpoint rule; e1 is oriented like e_ref."""

    def field(p: np.ndarray) -> np.ndarray:
        e = _direction(model1, model2, p, h_m, dh)[0]
        return np.where((e @ e_ref)[:, None] < 0, -e, e)

    out = np.empty((len(starts), n_steps + 1, 2))
    out[:, 0] = starts
    p = starts
    for k in range(n_steps):
        mid = p + 0.5 * length * field(p)
        p = p + length * field(mid)
        out[:, k + 1] = p
    return out


def epipolar_grid(
    model1: SensorModel,
    model2: SensorModel,
    box1: tuple[float, float, float, float],
    height_range: tuple[float, float],
    step: int = 16,
    margin: int = 8,
) -> EpipolarGrid:
    """The EpipolarGrid of the image-1 tile `box1` (x0, y0, x1, y1 px) over `height_range` (h_lo, h_hi).

    The grid spans the tile, widened along the rows by the disparity range (so that epipolar image 2
    holds every conjugate of the tile) and on every side by `margin` epipolar px (matching windows);
    `step` is the node spacing in epipolar px. Raises InputError where the pair has no epipolar
    geometry at the tile (see the module)."""
    lo, hi = (float(v) for v in height_range)
    h_m, dh = 0.5 * (lo + hi), max(0.5 * (hi - lo), MIN_HALF_RANGE_M)
    x0, y0, x1, y1 = (float(v) for v in box1)
    pc = np.array([[0.5 * (x0 + x1), 0.5 * (y0 + y1)]])
    qc = np.column_stack(predict(model1, model2, pc[:, 0], pc[:, 1], np.array([h_m])))
    if not np.isfinite(qc).all():
        raise InputError(
            f"the tile ({x0:.0f}, {y0:.0f}, {x1:.0f}, {y1:.0f}) of image 1 has no position in image 2 "
            f"at {h_m:.0f} m: the images do not overlap there"
        )
    e, parallax = _direction(model1, model2, pc, h_m, dh)
    if not parallax[0] >= MIN_PARALLAX_PX:
        raise InputError(
            f"the rays of the two images are parallel at the tile ({parallax[0]:.3g} px of parallax "
            f"over {2 * dh:.0f} m): no stereo base, no epipolar geometry; match a pair taken from "
            "different directions"
        )
    e = e[0]
    n = np.array([-e[1], e[0]])
    g1u, g1v, gsd1 = pixel_gsd(model1, pc[0, 0], pc[0, 1], h_m, e, n)
    t2 = np.column_stack(predict(model1, model2, pc[:, 0] + e[0], pc[:, 1] + e[1], np.array([h_m])))[0] - qc[0]
    gsd2 = pixel_gsd(model2, qc[0, 0], qc[0, 1], h_m, t2, np.array([-t2[1], t2[0]]))[2]
    gsd = max(gsd1, gsd2)
    su, sv = gsd / g1u, gsd / g1v  # image-1 px per epipolar px along e1, n1
    # disparity range at the centre, in epipolar px: image-2 parallax over the range / image-2 px per u
    q_lo, q_hi = (np.column_stack(predict(model1, model2, pc[:, 0], pc[:, 1], np.array([h])))[0] for h in (lo, hi))
    per_u = np.hypot(*t2) * su
    d_lo, d_hi = -np.hypot(*(q_lo - qc[0])) / per_u, np.hypot(*(q_hi - qc[0])) / per_u
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]]) - pc
    u_c, v_c = corners @ e / su, corners @ n / sv
    u_a = np.floor((u_c.min() + min(d_lo, 0.0) * 1.1 - margin) / step)
    u_b = np.ceil((u_c.max() + max(d_hi, 0.0) * 1.1 + margin) / step)
    v_a = np.floor((v_c.min() - margin) / step)
    v_b = np.ceil((v_c.max() + margin) / step)
    rows = np.arange(v_a, v_b + 1) * step
    starts = pc + rows[:, None] * sv * n[None, :]
    forward = _trace(model1, model2, starts, e, int(u_b), step * su, h_m, dh)
    backward = _trace(model1, model2, starts, e, int(-u_a), -step * su, h_m, dh)
    p = np.concatenate([backward[:, :0:-1], forward], axis=1)
    x2, y2 = predict(model1, model2, p[..., 0], p[..., 1], np.full(p.shape[:2], h_m))
    grid = EpipolarGrid(
        p=p,
        q=np.stack([x2, y2], axis=-1),
        u0=float(u_a * step),
        v0=float(v_a * step),
        step=int(step),
        heights=(lo, h_m, hi),
        gsd=gsd,
    )
    grid.row_error, grid.interpolation_error = grid_errors(model1, model2, grid)
    return grid


def grid_errors(model1: SensorModel, model2: SensorModel, grid: EpipolarGrid) -> tuple[float, float]:
    """(row_error, interpolation_error) of a grid at its cells' centres (see the module)."""
    rows, cols = grid.p.shape[:2]
    v, u = np.meshgrid(
        grid.v0 + (np.arange(rows - 1) + 0.5) * grid.step,
        grid.u0 + (np.arange(cols - 1) + 0.5) * grid.step,
        indexing="ij",
    )
    u, v = u.ravel(), v.ravel()
    x1, y1 = grid.image1(u, v)
    row, interp = [], np.nan
    for h in grid.heights:
        x2, y2 = predict(model1, model2, x1, y1, np.full(u.size, h))
        if h == grid.heights[1]:
            interp = np.nanmax(np.hypot(*(np.array(grid.image2(u, v)) - np.array([x2, y2]))))
        row.append(np.abs(grid.epipolar2(x2, y2)[1] - v))
    return float(np.nanmax(np.concatenate(row))), float(interp)


def disparity_range(
    model1: SensorModel, model2: SensorModel, grid: EpipolarGrid, height_range: Any, samples: int = 9
) -> tuple[float, float] | None:
    """(d_min, d_max), epipolar px: the disparities u2 - u of the grid's nodes (a samples x samples
    subset) at the heights of `height_range`, with NaN dropped; None where none is finite."""
    rows, cols = grid.p.shape[:2]
    a = np.unique(np.linspace(0, rows - 1, samples).round().astype(int))
    b = np.unique(np.linspace(0, cols - 1, samples).round().astype(int))
    aa, bb = (v.ravel() for v in np.meshgrid(a, b, indexing="ij"))
    p = grid.p[aa, bb]
    parts = []
    for h in height_range:
        x2, y2 = predict(model1, model2, p[:, 0], p[:, 1], np.full(len(p), float(h)))
        parts.append(grid.epipolar2(x2, y2)[0] - (grid.u0 + bb * grid.step))
    d = np.concatenate(parts)
    d = d[np.isfinite(d)]
    return (float(d.min()), float(d.max())) if d.size else None
