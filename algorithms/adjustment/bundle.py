"""Bundle adjustment of a block (Kornus et al. 2006, section 3.4).

Unknowns: the free orientation parameters (parameters.py) and every control/tie point (lon, lat,
h, updated in local metres east/north/up). Observations: image coordinates (sigma px) and the
ground coordinates of control points (sigma E/N/H m). Check points take no part; they are
intersected afterwards with the adjusted models (`check_points`). Gauss-Newton on the normal
equations reduced by the object points (normals.py), so the cost is linear in the points. Points
start on their lines of sight (`start_points`); the statistics use the last iteration's
linearisation with the misclosures carried to the solution (its update is below the tolerance).

Statistics (after convergence): sigma_0^2 = v'Pv / r with r = observations - unknowns; the
cofactors Q_oo = N^-1 of the orientation unknowns and the points'; redundancy numbers r_i of
every image observation; normalised residuals w_i = v_i / (sigma_i sqrt(r_i)) (Baarda's data
snooping with the a priori sigma; |w| > `critical`, default 3.29 = alpha 0.1 %, flags a blunder).
With `remove_blunders`, the worst flagged measurement is removed and the block re-adjusted until
none is flagged (each removal reported).

Prior information on orientation unknowns (e.g. an RPC bias known to be a few pixels, the offset
of a trajectory known to 1000 m) enters as direct observations x_q = 0 with sigma_q: weight
1/sigma_q^2 on the diagonal of the reduced normal matrix; they count in the redundancy and in v'Pv.

Datum defects and parameters the points cannot determine are found on the normal matrix (with the
priors) before solving (correlation-scaled eigen-decomposition) and reported by name; a matrix that
its Cholesky factorisation finds singular in a later iteration is reported the same way.

Failure modes, each an error naming its cause, never a NaN carried on: a measurement whose sensor model
gives no finite image position or derivatives (GeometryError naming the points and images: a point
outside a model's domain in the first iteration, an adjustment that diverged later); a point its rays
do not determine; a non-finite update. Control points without an image measurement take no part
(noted in the log). An adjustment that does not converge within `max_iterations` returns with
`converged` False and says so in its log; the caller decides (adjust_block stores nothing).

The kernels run on the calling thread for small blocks (normals.kernel_threads)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import progress
from ..errors import CancelledError, GeometryError, InputError
from ..geodesy import metres_per_degree, offset_enu
from ..progress import Feedback
from ..surface.intersection import Measurements, closest_points, intersect
from . import normals
from .observations import Observations
from .parameters import OrientationParameters

CRITICAL_W = 3.29
#: an eigenvalue of the correlation-scaled reduced normal matrix below this is a defect: that
#: combination of unknowns would be over 1000 times less precise than the unknowns alone
DEFECT_EIGENVALUE = 1e-6
#: an unknown belongs to a defect when its component in the (unit, correlation-scaled) eigenvector exceeds
#: this: an exterior constant whose effect the points absorb has a small scaled component (a common roll
#: against the images' psi_y constants), yet fixing it is what removes the defect
DEFECT_MEMBER = 1e-3


@dataclass
class AdjustmentSettings:
    """How `adjust` solves. At most `max_iterations` Gauss-Newton iterations, converged when the largest
    point update is below `tolerance` (m). With `remove_blunders`, the worst measurement whose |w| exceeds
    `critical` is removed and the block adjusted again, at most `max_removals` times. `priors`: {name or
    pattern: sigma} prior observations x = 0 of orientation unknowns (see `prior_sigmas`), merged over the
    model's own (OrientationParameters.default_priors; a user sigma of inf drops one). `model`,
    `orientation_images`: the exterior orientation model (parameters.py: "polynomial" or "lagrange").
    `defect_eigenvalue`: see find_defects (selection.py tests weaker parameters on their significance).
    `effects`: compute each free unknown's largest image effect for the report (parameters.max_effects;
    NaN without: the selection's trials do not need them)."""

    max_iterations: int = 15
    tolerance: float = 1e-4
    remove_blunders: bool = False
    critical: float = CRITICAL_W
    max_removals: int = 50
    priors: dict[str, float] | None = None
    model: str = "polynomial"
    orientation_images: int = 4
    defect_eigenvalue: float = DEFECT_EIGENVALUE
    effects: bool = True


@dataclass
class Adjustment:
    """Result of `adjust` (all arrays over the adjusted points / measurements)."""

    parameters: OrientationParameters  # the models now carry the solution
    values: np.ndarray  # all orientation unknowns (fixed ones 0)
    sigmas: np.ndarray  # their standard deviations (NaN: fixed)
    covariance: np.ndarray  # (nfree, nfree) of the free unknowns, sigma_0^2 Q_oo
    sigma0: float
    redundancy: int  # observations - unknowns
    observations: Observations  # the points and measurements that were adjusted
    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    point_sigmas: np.ndarray  # (P, 3) sigma E, N, H (m)
    residuals: np.ndarray  # (M, 2) image residuals v = computed - measured (px)
    redundancy_numbers: np.ndarray  # (M, 2)
    normalised: np.ndarray  # (M, 2) w = v / (sigma sqrt(r))
    ground_residuals: np.ndarray  # (P, 3) E, N, H of computed - observed (control points; NaN else)
    iterations: int
    converged: bool  # the last point update was below the tolerance
    last_update: float  # the last iteration's largest point update (m)
    effects: np.ndarray  # largest image effect (px) of each free unknown (NaN: fixed)
    removed: list = field(default_factory=list)  # (point name, image id, w) of removed blunders
    log: list = field(default_factory=list)
    notes: list = field(default_factory=list)  # what the report must say: points left out, not converged

    def flagged(self, critical=CRITICAL_W):
        """Indices of measurements with |w| > critical in col or row."""
        return np.flatnonzero(np.nanmax(np.abs(self.normalised), axis=1) > critical)


class _Geometry:
    """The image measurements of `obs` sorted by point (`start[p]:start[p + 1]` are point p's),
    their weights, and each image's free unknowns: `col` (n_images, K) their index among the free
    unknowns (-1: none; K the most free unknowns one image depends on), `map_entries[s]` the non-zero
    entries (coefficient, compact column, value) of the image's map from its coefficients to those
    compact columns, and `rows[s]` its measurements."""

    def __init__(self, params, obs):
        self.params = params
        self.images = sorted(params.models)
        self.order = np.argsort(obs.measurements["point"], kind="stable")
        self.meas = obs.measurements[self.order]
        self.point_of = self.meas["point"]
        self.start = np.searchsorted(self.point_of, np.arange(len(obs.points) + 1))
        self.img = np.searchsorted(self.images, self.meas["image_id"]).astype(np.int64)
        self.rows = [np.flatnonzero(self.img == s) for s in range(len(self.images))]
        self.w = np.repeat((1.0 / self.meas["sigma"] ** 2)[:, None], 2, axis=1)
        free_index = np.full(len(params), -1, np.int64)
        free_index[params.free] = np.arange(params.free.sum())
        self.nfree = int(params.free.sum())
        used = [np.flatnonzero(np.any(params.jacobian_map(i) != 0.0, axis=0) & (free_index >= 0)) for i in self.images]
        width = max([u.size for u in used], default=0)
        self.col = np.full((len(self.images), width), -1, np.int64)
        self.map_entries = []
        for s, i in enumerate(self.images):
            tmap = params.jacobian_map(i)
            self.col[s, : used[s].size] = free_index[used[s]]
            compact = np.zeros((tmap.shape[0], width))
            compact[:, : used[s].size] = tmap[:, used[s]]
            coef, cols = np.nonzero(compact)
            self.map_entries.append((coef, cols, compact[coef, cols]))
        # the exterior orientation's partials are needed where one of its coefficients is free
        self.exterior = [
            bool((e[0] < params.models[i].EXTERIOR_COEFFICIENTS).any()) for e, i in zip(self.map_entries, self.images)
        ]

    def point_orientation_blocks(self, a, b):
        """sum_j A_j' W B_j per point, (P, 3, nfree): the coupling of each point with the free
        orientation unknowns (normals.py's C)."""
        dense = np.zeros((len(self.meas), 2, self.nfree))
        for s, k in enumerate(self.rows):
            used = np.flatnonzero(self.col[s] >= 0)
            dense[np.ix_(k, [0, 1], self.col[s, used])] = b[np.ix_(k, [0, 1], used)]
        per_meas = np.einsum("jer,je,jeq->jrq", a, self.w, dense)
        return np.add.reduceat(per_meas, self.start[:-1], axis=0) if len(per_meas) else per_meas

    def linearise(self, lon, lat, h):
        """(a, b, l): a (M, 2, 3) px/m, b (M, 2, K) compact orientation partials, l = measured -
        computed (M, 2) px."""
        n = len(self.meas)
        a, b = np.empty((n, 2, 3)), np.empty((n, 2, self.col.shape[1]))
        l = np.column_stack([self.meas["col"], self.meas["row"]])
        e_deg, n_deg = metres_per_degree(lat, h)
        per_metre = np.column_stack([1.0 / e_deg, 1.0 / n_deg, np.ones_like(e_deg)])
        for s, k in enumerate(self.rows):
            if not k.size:
                continue
            p = self.point_of[k]
            d = self.params.models[self.images[s]].partials(lon[p], lat[p], h[p], exterior=self.exterior[s])
            normals.scatter_partials(k, d["d_corrections"], d["d_ground"], per_metre[p], *self.map_entries[s], b, a)
            l[k, 0] -= d["col"]
            l[k, 1] -= d["row"]
        return a, b, l

    def design(self, a: np.ndarray, b: np.ndarray) -> normals.Design:
        """The kernels' view (normals.Design) of the measurements with the partials a, b of `linearise`."""
        return normals.Design(self.start, a, b, self.w, self.img, self.col)


def _ground_weights(points, lon, lat, h):
    """(wg, lg): weights (P, 3) and misclosures observed - current (P, 3, m E/N/U) of control points."""
    control = points["role"] == "control"
    wg = np.zeros((len(points), 3))
    lg = np.zeros((len(points), 3))
    sig = np.column_stack([points["sigma_e"], points["sigma_n"], points["sigma_h"]])
    wg[control] = 1.0 / sig[control] ** 2
    e_deg, n_deg = metres_per_degree(lat, h)
    lg[control, 0] = (points["lon"][control] - lon[control]) * e_deg[control]
    lg[control, 1] = (points["lat"][control] - lat[control]) * n_deg[control]
    lg[control, 2] = points["h"][control] - h[control]
    return wg, lg


def start_points(models, obs, height):
    """Starting lon, lat, h and a usable mask: control points at their observed coordinates, the
    others at the point closest to their lines of sight (surface.intersection.closest_points, the
    lines through the ground points at `height`, a mean terrain height, -+ 500 m): the adjustment
    refines them with everything else, so no per-point adjustment first. Points with fewer than
    two usable, non-parallel lines are not usable."""
    p, m = obs.points, obs.measurements
    lon, lat, h = p["lon"].copy(), p["lat"].copy(), p["h"].copy()
    usable = p["role"] == "control"
    rest = np.isin(m["point"], np.flatnonzero(~usable))
    if rest.any():
        ids, lon_r, lat_r, h_r, ok = closest_points(
            models, m["image_id"][rest], m["point"][rest], m["col"][rest], m["row"][rest], h0=height
        )
        lon[ids], lat[ids], h[ids] = lon_r, lat_r, h_r
        usable[ids] = ok
    return lon, lat, h, usable


class DefectError(InputError):
    """Orientation unknowns the observations cannot determine; `groups` lists, per defect, the
    names of the unknowns involved (most involved first)."""

    def __init__(self, message, groups):
        super().__init__(message)
        self.groups = groups


def defect_groups(normal, labels, threshold=DEFECT_EIGENVALUE, prior=None):
    """The unknowns the reduced normal matrix cannot determine, as groups of labels ([] if regular):
    each unknown nothing depends on alone, and per eigenvector of the correlation-scaled matrix with
    an eigenvalue below `threshold` the unknowns it involves (|component| > DEFECT_MEMBER, most
    involved first: fixing any one of them removes that combination). `prior`: the prior weights
    included in `normal` (diagonal); a combination they hold (a positive share of half its eigenvalue
    or more) is determined by the user's priors, however weak, and not reported. An exact defect's
    eigenvalue comes out of the decomposition as +-1e-16 or so: without priors it is always reported."""
    diag = np.diag(normal).copy()
    groups = [[labels[q]] for q in np.flatnonzero(diag <= 0)]
    good = np.flatnonzero(diag > 0)
    if good.size:
        d = 1.0 / np.sqrt(diag[good])
        scaled = np.ascontiguousarray(normal[np.ix_(good, good)] * d[:, None] * d[None, :])
        if _clearly_regular(scaled, threshold):
            return groups
        vals, vecs = np.linalg.eigh(scaled)
        held = (np.zeros(normal.shape[0]) if prior is None else np.asarray(prior, float))[good] * d * d
        for v, vec in zip(vals, vecs.T):
            if v > threshold * max(vals[-1], 1.0):
                break
            share = float(np.sum(held * vec * vec))
            if share > 0.0 and share >= 0.5 * v:
                continue
            order = np.argsort(-np.abs(vec))
            groups.append([labels[good[q]] for q in order[np.abs(vec[order]) > DEFECT_MEMBER]])
    return groups


def _clearly_regular(m, threshold):
    """True where every eigenvalue of the symmetric m is provably above threshold * max(largest, 1):
    lambda_min >= 1 / ||m^-1||_inf and lambda_max <= ||m||_inf (a Cholesky inverse; saves the
    eigendecomposition in the usual, regular case)."""
    inv = np.empty(m.shape)
    if not normals.cholesky_solve(m, np.eye(len(m)), inv):
        return False
    return 1.0 / np.abs(inv).sum(axis=1).max() > threshold * max(np.abs(m).sum(axis=1).max(), 1.0)


def find_defects(normal, labels, threshold=DEFECT_EIGENVALUE, prior=None):
    """DefectError naming the unknowns of `defect_groups` (the four most involved of each; None
    if the matrix is regular)."""
    groups = defect_groups(normal, labels, threshold, prior)
    if not groups:
        return None
    unused = np.diag(normal) <= 0
    parts = [
        f"{g[0]} (no measurement depends on it)" if len(g) == 1 and unused[labels.index(g[0])] else " with ".join(g[:4])
        for g in groups
    ]
    return DefectError(
        "these orientation parameters cannot be determined from these points: "
        + "; ".join(parts)
        + ". Add control points (or spread them wider), fix these parameters or give them "
        "prior sigmas",
        groups,
    )


def prior_sigmas(params, priors):
    """Array over all unknowns of their prior sigmas (inf: no prior) from {name or pattern: sigma}
    (patterns as parameters.OrientationParameters.select; sigmas in internal units m, rad, px)."""
    sigma = np.full(len(params), np.inf)
    for spec, value in (priors or {}).items():
        if not value > 0:
            raise InputError(f"the prior sigma of {spec!r} must be positive, not {value}")
        sigma[params.select([spec])] = value
    return sigma


def adjust(
    models: dict[int, Any],
    observations: Observations,
    free: np.ndarray | list[str],
    names: dict[int, str] | None = None,
    height: float = 0.0,
    settings: AdjustmentSettings | None = None,
    feedback: Feedback | None = None,
) -> Adjustment:
    """Bundle adjustment (module docstring). models {image_id: model} (edited in place: they carry
    the solution); observations: Observations (check points are ignored here); free: bool mask or
    a list of names/patterns for parameters.OrientationParameters.select; height: mean terrain
    height for the tie points' starting values; settings: AdjustmentSettings (default: its defaults).
    Returns an Adjustment; raises InputError on too few observations or undeterminable parameters
    (named), CancelledError when cancelled."""
    settings = settings or AdjustmentSettings()
    obs = observations.check()
    params = OrientationParameters(models, names, settings.model, settings.orientation_images)
    mask = np.asarray(free, bool) if np.asarray(free).dtype == bool else params.select(free)
    if mask.shape != (len(params),):
        raise InputError(f"the free-parameter mask has {mask.size} entries for {len(params)} parameters")
    params.free = mask
    params.prior_weights = 1.0 / prior_sigmas(params, {**params.default_priors, **(settings.priors or {})}) ** 2
    unknown = set(np.unique(obs.measurements["image_id"])) - set(models)
    if unknown:
        raise InputError(f"measurements in image id(s) {sorted(unknown)} that the block has no model for")
    used = obs.subset(obs.points["role"] != "check")
    removed: list[tuple[str, int, float]] = []
    while True:
        with normals.kernel_threads(len(used.measurements)):
            result = _solve(params, used, height, settings, feedback)
        result.removed = removed
        bad = result.flagged(settings.critical)
        if not settings.remove_blunders or not bad.size or len(removed) >= settings.max_removals:
            return result
        worst = bad[np.argmax(np.nanmax(np.abs(result.normalised[bad]), axis=1))]
        mw = result.observations.measurements[worst]
        name = result.observations.points["name"][mw["point"]]
        wmax = float(np.nanmax(np.abs(result.normalised[worst])))
        removed.append((str(name), int(mw["image_id"]), wmax))
        progress.ensure(feedback).pushInfo(
            f"data snooping: removed the measurement of {name} in "
            f"{params.names[int(mw['image_id'])]} (|w| = {wmax:.1f}); re-adjusting"
        )
        keep = np.ones(len(used.measurements), bool)
        keep[_measurement_index(used, result.observations, worst)] = False
        used = Observations(used.points, used.measurements[keep])


def _measurement_index(used, adjusted, k):
    """Index in `used` of measurement k of `adjusted` (same point name and image)."""
    mk = adjusted.measurements[k]
    name = adjusted.points["name"][mk["point"]]
    point = np.flatnonzero(used.points["name"] == name)[0]
    return np.flatnonzero((used.measurements["point"] == point) & (used.measurements["image_id"] == mk["image_id"]))


def _measured(obs, notes):
    """`obs` without its control points that have no image measurement (noted): with nothing but their
    ground coordinates they would only fit themselves."""
    control = obs.points["role"] == "control"
    unmeasured = control & (np.bincount(obs.measurements["point"], minlength=len(obs.points)) == 0)
    if not unmeasured.any():
        return obs
    names = obs.points["name"][unmeasured]
    notes.append(
        f"{names.size} control point(s) without an image measurement take no part: {_named(names, 10)} "
        "(measure them in at least one image to use them)"
    )
    return obs.subset(~unmeasured)


def _solve(
    params: OrientationParameters,
    obs: Observations,
    height: float,
    settings: AdjustmentSettings,
    feedback: Feedback | None,
) -> Adjustment:
    """One adjustment of `obs` (no data snooping): the body of `adjust`."""
    max_iterations, tolerance = settings.max_iterations, settings.tolerance
    notes: list[str] = []
    fb = progress.ensure(feedback)
    obs = _measured(obs, notes)
    lon, lat, h, usable = start_points(params.models, obs, height)
    if not usable.all():
        notes.append(
            f"{(~usable).sum()} point(s) left out: they cannot be intersected (fewer than two rays, "
            f"outside an image or no convergence): {_named(obs.points['name'][~usable])}"
        )
        obs = obs.subset(usable)
        lon, lat, h = lon[usable], lat[usable], h[usable]
    pts = obs.points
    if not len(pts):
        raise InputError("no point can be intersected from its image measurements: nothing to adjust")
    log = list(notes)
    geo = _Geometry(params, obs)
    col, nfree = geo.col, geo.nfree
    labels = [params.label(q) for q in np.flatnonzero(params.free)]
    prior = params.prior_weights[params.free]
    x = np.zeros(len(params))
    n_pts = len(pts)
    blocks = normals.PointBlocks(np.zeros((n_pts, 3, 3)), np.zeros((n_pts, 3)), np.zeros(n_pts, bool))
    ok = blocks.ok
    dx = np.zeros((n_pts, 3))
    params.apply(x)
    iteration, converged = 0, False
    for iteration in range(1, max_iterations + 1):
        if fb.isCanceled():
            raise CancelledError("bundle adjustment cancelled")
        a, b, l, wg, normal, rhs, cost = _linearise(geo, pts, (lon, lat, h), prior, x[params.free], blocks)
        _check_linearisation(geo, pts, (lon, lat, h), (a, b, l, normal, rhs), ok, iteration)
        if iteration == 1:
            defects = find_defects(normal, labels, settings.defect_eigenvalue, prior)
            if defects:
                raise defects
            n_obs, redundancy = _redundancy(geo, pts, ok, prior)
            if redundancy <= 0:
                raise InputError(
                    f"too few observations: {n_obs} for {n_obs - redundancy} unknowns ({nfree} "
                    f"orientation, 3 per point): measure more points, in more images, or fix "
                    "parameters"
                )
        do = _solve_scaled(normal, rhs, labels, prior)
        normals.back_substitute(geo.design(a, b), blocks, do, dx)
        step = float(np.max(np.abs(dx))) if n_pts else 0.0
        if not (np.isfinite(step) and np.isfinite(do).all()):
            raise GeometryError(
                f"the adjustment's update in iteration {iteration} is not finite: the normal "
                "equations are numerically singular. " + _DIVERGED
            )
        x[params.free] += do
        params.apply(x)
        lon, lat, h = offset_enu(lon, lat, h, dx)
        log.append(f"iteration {iteration}: weighted misclosure {cost:.6g}, largest point update {step:.3g} m")
        fb.setProgress(min(99.0, 100.0 * iteration / max_iterations))
        if step < tolerance:
            converged = True
            break
    else:
        notes.append(
            f"NOT CONVERGED in {max_iterations} iteration(s): the last point update was {step:.3g} m "
            f"(tolerance {tolerance:g} m); the solution and its statistics are not those of the least "
            "squares adjustment"
        )
        log.append(notes[-1])
    # statistics at the solution
    if converged:
        # the last update was below the tolerance: its linearisation holds at the solution, where the
        # misclosures are l - A dx - B do (the neglected second-order terms are below 1e-9 px)
        dof = np.where(col >= 0, np.r_[do, 0.0][col], 0.0)
        l = l - np.einsum("jer,jr->je", a, dx[geo.point_of]) - np.einsum("jek,jk->je", b, dof[geo.img])
    else:
        a, b, l, wg, normal, rhs, _ = _linearise(geo, pts, (lon, lat, h), prior, x[params.free], blocks)
        _check_linearisation(geo, pts, (lon, lat, h), (a, b, l, normal, rhs), ok, iteration + 1)
    lg = _ground_weights(pts, lon, lat, h)[1]
    vpv_prior = float(np.sum(prior * x[params.free] ** 2))
    qoo = _inverse_scaled(normal, labels, prior)
    qpp = np.zeros((n_pts, 3, 3))
    red = np.zeros((len(geo.meas), 2))
    normals.point_statistics(geo.design(a, b), blocks, qoo, qpp, red)
    v = -l
    vg = -lg
    control = pts["role"] == "control"
    redundancy = _redundancy(geo, pts, ok, prior)[1]
    vpv = float(np.sum(v * v * geo.w) + np.sum(vg * vg * wg)) + vpv_prior
    sigma0 = s0 = float(np.sqrt(vpv / redundancy))  # redundancy > 0: checked in the first iteration
    sigmas = np.full(len(params), np.nan)
    sigmas[params.free] = s0 * np.sqrt(np.diag(qoo))
    sig_l = 1.0 / np.sqrt(geo.w)
    normalised = v / (sig_l * np.sqrt(np.clip(red, 1e-12, None)))
    ground_res = np.full((n_pts, 3), np.nan)
    ground_res[control] = vg[control]
    back = np.empty_like(geo.order)
    back[geo.order] = np.arange(len(geo.order))
    log.append(
        f"sigma_0 {sigma0:.4f} (a priori 1), redundancy {redundancy}, {nfree} orientation unknowns, "
        f"{n_pts} points, {len(geo.meas)} image measurements"
    )
    for line in log:
        fb.pushInfo(line)
    return Adjustment(
        parameters=params,
        values=x.copy(),
        sigmas=sigmas,
        covariance=s0**2 * qoo,
        sigma0=sigma0,
        redundancy=redundancy,
        observations=obs,
        lon=lon,
        lat=lat,
        h=h,
        point_sigmas=s0 * np.sqrt(np.abs(np.diagonal(qpp, axis1=1, axis2=2))),
        residuals=v[back],
        redundancy_numbers=red[back],
        normalised=normalised[back],
        ground_residuals=ground_res,
        iterations=iteration,
        converged=converged,
        last_update=step,
        effects=params.max_effects(x, height) if settings.effects else np.full(len(params), np.nan),
        log=log,
        notes=notes,
    )


#: what to do when the adjustment diverges
_DIVERGED = (
    "Free fewer parameters (e.g. FREE look:0), give them prior sigmas, add control points or check "
    "them and their measurements for gross errors"
)


def _named(names, limit=5):
    """Up to `limit` distinct names, comma-separated, with "..." when there are more."""
    unique = list(dict.fromkeys(str(n) for n in names))
    return ", ".join(unique[:limit]) + (" ..." if len(unique) > limit else "")


def _check_linearisation(geo, pts, position, arrays, ok, iteration):
    """Raise GeometryError naming the cause of a NaN or infinity in a linearisation (a, b, l, N, b of
    `_linearise`) or of a point its rays do not determine (`ok` False): the measurements (points and
    images) whose model gives no finite position or derivatives, at `position` (lon, lat, h)."""
    a, b, l, normal, rhs = arrays
    bad = ~(np.isfinite(a).all(axis=(1, 2)) & np.isfinite(b).all(axis=(1, 2)) & np.isfinite(l).all(axis=1))
    if bad.any():
        points = pts["name"][geo.point_of[bad]]
        images = [geo.params.names[geo.images[s]] for s in geo.img[bad]]
        p = geo.point_of[np.flatnonzero(bad)[0]]
        lon, lat, h = (float(c[p]) for c in position)
        where = f"point {pts['name'][p]} at lon {lon:.6f}, lat {lat:.6f}, h {h:.1f} m"
        if iteration == 1:
            cause = (
                "where these points start, the sensor models give no image position: they lie outside the "
                "models' valid domain (check their coordinates and measurements, or leave them out)"
            )
        else:
            cause = (
                f"the adjustment diverged: its update in iteration {iteration - 1} moved the orientation or "
                f"the points where the sensor models are not valid. {_DIVERGED}"
            )
        raise GeometryError(
            f"{int(bad.sum())} image measurement(s) have no finite image position or derivatives "
            f"(points {_named(points)}; images {_named(images)}; first: {where}): {cause}"
        )
    if not ok.all():
        raise GeometryError(
            f"the image rays of point(s) {_named(pts['name'][~ok])} do not determine them in "
            f"iteration {iteration} (parallel rays): leave them out or measure them in an image "
            f"that sees them from another direction"
        )
    if not (np.isfinite(normal).all() and np.isfinite(rhs).all()):
        raise GeometryError(
            f"the normal equations of iteration {iteration} overflow (not finite) although every "
            "image position and derivative is finite: check the sigmas of the measurements and "
            "control points (none may be near 0) and the priors"
        )


def _redundancy(geo, pts, ok, prior):
    """(observations, redundancy = observations - unknowns) of the usable points `ok`: 2 per image
    measurement, 3 per control point and 1 per prior, against 3 per point and the free unknowns."""
    n_obs = (
        2 * int(ok[geo.point_of].sum())
        + 3 * int(((pts["role"] == "control") & ok).sum())
        + int(np.count_nonzero(prior))
    )
    return n_obs, n_obs - 3 * int(ok.sum()) - geo.nfree


def _linearise(
    geo: _Geometry,
    pts: np.ndarray,
    position: tuple[np.ndarray, np.ndarray, np.ndarray],
    prior: np.ndarray,
    xfree: np.ndarray,
    blocks: normals.PointBlocks,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Linearise at `position` (lon, lat, h) and the models' orientation, and reduce the normal equations
    by the points (normals.reduce_normals fills `blocks`), with the priors of the free unknowns `xfree`.
    Returns a, b, l (_Geometry.linearise), the ground weights, N, b and the weighted misclosure."""
    lon, lat, h = position
    a, b, l = geo.linearise(lon, lat, h)
    wg, lg = _ground_weights(pts, lon, lat, h)
    normal, rhs = np.zeros((geo.nfree, geo.nfree)), np.zeros(geo.nfree)
    cost = normals.reduce_normals(geo.design(a, b), l, normals.Ground(wg, lg), geo.nfree, normal, rhs, blocks)
    cost += _add_priors(normal, rhs, prior, xfree)
    return a, b, l, wg, normal, rhs, cost


def _add_priors(normal, rhs, weights, x):
    """Prior observations 0 = x + dx (weights 1/sigma^2) into N and b (in place); returns their x'Px."""
    normal[np.diag_indices_from(normal)] += weights
    rhs -= weights * x
    return float(np.sum(weights * x * x))


def _scaled(normal):
    d = np.sqrt(np.diag(normal))
    d[d == 0] = 1.0
    return 1.0 / d


def _solve_jacobi(normal, rhs, labels=None, prior=None):
    """N^-1 rhs (rhs (n, k)) with Jacobi scaling (unknowns of m and rad mixed) by Cholesky
    (normals.cholesky_solve). A matrix it finds not positive definite is singular to rounding (the
    normal equations are positive semi-definite, and regular by find_defects in the first
    iteration): DefectError naming the combinations of `labels` (default "unknown <k>"; prior: the
    priors' weights in N) whose eigenvalues are below DEFECT_EIGENVALUE, or else the one of the
    smallest eigenvalue."""
    s = _scaled(normal)
    scaled = np.ascontiguousarray(normal * s[:, None] * s[None, :])
    out = np.empty(rhs.shape)
    if normals.cholesky_solve(scaled, np.ascontiguousarray(rhs * s[:, None]), out):
        return out * s[:, None]
    labels = labels or [f"unknown {k}" for k in range(len(normal))]
    error = find_defects(normal, labels, DEFECT_EIGENVALUE, prior)
    if error is None:
        vec = np.linalg.eigh(scaled)[1][:, 0]
        order = np.argsort(-np.abs(vec))
        group = [labels[q] for q in order[np.abs(vec[order]) > DEFECT_MEMBER]]
        error = DefectError(
            "the normal equations became singular during the iteration, in the combination of "
            + " with ".join(group[:4])
            + ". Fix some of these parameters or give them prior "
            "sigmas",
            [group],
        )
    raise error


def _solve_scaled(normal, rhs, labels=None, prior=None):
    """Solve N x = b (_solve_jacobi)."""
    if not normal.size:
        return np.zeros(0)
    return _solve_jacobi(normal, rhs[:, None], labels, prior)[:, 0]


def _inverse_scaled(normal, labels=None, prior=None):
    """N^-1 (_solve_jacobi)."""
    if not normal.size:
        return np.zeros((0, 0))
    return _solve_jacobi(normal, np.eye(len(normal)), labels, prior)


def check_points(adjustment: Adjustment, observations: Observations, height: float = 0.0) -> dict[str, Any]:
    """Intersect the check points of `observations` with the adjusted models and compare with
    their ground coordinates. Returns a dict: names, dE, dN, dH (m, computed - reference) and
    the theoretical sigma E/N/H of each: the intersection's own (image sigmas scaled by sigma_0)
    plus the orientation covariance propagated, C = Ni + G C_oo G' (G = -Ni sum C_j, normals.py),
    plus the check point's own ground sigma; "left_out": the names of the check points that cannot be
    intersected (fewer than two measurements, parallel rays)."""
    with normals.kernel_threads(len(observations.measurements)):
        return _check_points(adjustment, observations, height)


def _check_points(adjustment: Adjustment, observations: Observations, height: float) -> dict[str, Any]:
    params = adjustment.parameters
    chk = observations.subset(observations.points["role"] == "check")
    m = chk.measurements
    if not len(m):
        return {
            "names": chk.points["name"][:0],
            "dE": np.zeros(0),
            "dN": np.zeros(0),
            "dH": np.zeros(0),
            "sigma": np.zeros((0, 3)),
            "left_out": list(chk.points["name"]),
        }
    cut = intersect(params.models, Measurements(m["image_id"], m["point"], m["col"], m["row"], m["sigma"]), h0=height)
    left_out = list(chk.points["name"][~np.isin(np.arange(len(chk.points)), cut.point[cut.ok])])
    chk = chk.subset(np.isin(np.arange(len(chk.points)), cut.point[cut.ok]))
    pts = chk.points
    lon, lat, h, ninv = cut.lon[cut.ok], cut.lat[cut.ok], cut.h[cut.ok], cut.covariance[cut.ok]
    geo = _Geometry(params, chk)
    a, b, _ = geo.linearise(lon, lat, h)
    g = -ninv @ geo.point_orientation_blocks(a, b)
    cov = adjustment.sigma0**2 * ninv + g @ adjustment.covariance @ np.swapaxes(g, 1, 2)
    e_deg, n_deg = metres_per_degree(pts["lat"], pts["h"])
    ground = np.column_stack([pts["sigma_e"], pts["sigma_n"], pts["sigma_h"]])
    return {
        "names": pts["name"],
        "dE": (lon - pts["lon"]) * e_deg,
        "dN": (lat - pts["lat"]) * n_deg,
        "dH": h - pts["h"],
        "sigma": np.sqrt(np.diagonal(cov, axis1=1, axis2=2) + np.nan_to_num(ground) ** 2),
        "left_out": left_out,
    }


class Restart:
    """Repeated adjustments of one block, each from the orientation the models had when this was
    made (the supplied one), so fixed parameters and priors keep their meaning: the variance
    components and the parameter selection. `observations` is the default set, `height` and `settings`
    those of every run (adjust); `count` the runs; the `settings` of a call replace them for that run."""

    def __init__(
        self,
        models: dict[int, Any],
        observations: Observations,
        names: dict[int, str] | None = None,
        feedback: Feedback | None = None,
        height: float = 0.0,
        settings: AdjustmentSettings | None = None,
    ) -> None:
        self.base = OrientationParameters(models, names)
        self.models, self.observations, self.names = models, observations, names
        self.feedback, self.height, self.settings = feedback, height, settings or AdjustmentSettings()
        self.count = 0

    def __call__(
        self, free: list[str], observations: Observations | None = None, settings: AdjustmentSettings | None = None
    ) -> Adjustment:
        self.base.apply(np.zeros(len(self.base)))
        self.count += 1
        return adjust(
            self.models,
            self.observations if observations is None else observations,
            list(free),
            names=self.names,
            height=self.height,
            settings=self.settings if settings is None else settings,
            feedback=progress.quiet(self.feedback),
        )
