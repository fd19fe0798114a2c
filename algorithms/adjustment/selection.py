"""Automatic selection of the free orientation parameters (Kornus et al. 2006, section 3.4.3).

Step 1: the look-angle correction coefficients (degree 0-`look_degree` of psi_x, psi_y of every
SPOT image; the affine bias of every RPC image) are estimated with the exterior ones fixed. Those
whose significance |x| / sigma_x is below `significance` are fixed (to the supplied value, i.e. an
increment of 0) one at a time, the least significant first, each followed by a new adjustment. Of
a look-angle polynomial (an image's psi_x or psi_y over the detector) only the highest free degree
is a candidate: it keeps its lower degrees while a higher one is free. Over the detector, centred,
the constant and the quadratic term are strongly correlated, so either may look insignificant
alone; fixing the constant would leave the quadratic and cubic terms to stand in for a shift, and
they extrapolate it wildly towards the image borders. (The exterior polynomials over time are not
held so: their constants stand in for the images' look-angle constants, and those are preferred.)
A coefficient stays free, whatever its significance, when fixing it makes the control point
residuals larger (image RMS per image, or ground RMS per E/N/H) or systematic (a mean residual of
the control points in an image that a t-test finds non-zero, when it was not before).
"Larger" means up by more than `max_increase` of the RMS, and by more than chance explains: the m
control residuals concerned (2 per measurement in an image, or one per control point in E, N or H)
gain more than significance^2 in their share of v'Pv, m (RMS_new^2 - RMS_old^2) / sigma^2 >
significance^2 (the chi-square(1) quantile of the significance test's alpha: fixing one
coefficient that is truly zero raises the whole v'Pv by chi-square(1)). Control residuals far
below their sigma, or a few control points that an over-flexible set fits exactly, can thus grow
without keeping the coefficient. `systematic` is the t-test's threshold as a normal quantile (3.0:
alpha 0.27 %, two-sided); with n control measurements in an image the mean over their sigma
follows Student's t with n - 1 degrees of freedom, so the threshold is its quantile of the same
alpha (`t_threshold`; 6.6 for five control points, where a plain 3.0 is exceeded by chance in 4 %
of the tests, not 0.27 %).
Step 2: the exterior coefficients (degree 0-`exterior_degree` of every trajectory) are tested with
the chosen look-angle set, first the attitude (yaw, pitch, roll), then the position (X, Y, Z):
the orbit is better known than the attitude, and a position drift can mimic an attitude drift.
They join the chosen set as free unknowns; those the points cannot determine together with the
rest are fixed first (find_defects; of each defect the highest-degree exterior coefficient), then
the insignificant ones are fixed as in step 1. Only exterior coefficients are fixed here: look
angles and exterior angles (and positions) can stand in for each other, and Kornus et al.'s preference is
the look angles. All coefficients are estimated jointly and the final adjustment carries the full
covariance. (K held the look-angle set fixed at its step-1 values instead; then a trajectory
drift, whose image-wise constant parts the look-angle constants have already absorbed, could
never be found.)
Step 3 (only when step 2 added exterior coefficients): the look-angle coefficients of step 1 are
tested once more in the same way, now with the exterior ones free: a look-angle constant that
stood in for an attitude drift in step 1 is no longer significant.

Unknowns the points cannot determine at all in step 1 are fixed in the same way (highest degree
first). Every step is logged; the user overrides the result by giving the free set explicitly."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.special import ndtr, stdtrit

from .. import progress
from ..errors import InputError
from ..progress import Feedback
from .bundle import Adjustment, AdjustmentSettings, DefectError, Restart
from .observations import Observations
from .parameters import EXTERIOR, LOOK
from .variance import Component, estimate

#: eigenvalue threshold of the defect test while selecting (bundle.find_defects): only numerically
#: singular combinations are fixed before solving; weakly determined ones are left to the significance test
SELECTION_DEFECT_EIGENVALUE = 1e-10
#: preference when one coefficient of a defect must be fixed: first by degree (highest first),
#: then by kind in this order (positions before attitudes before look angles)
FIX_ORDER = ("X", "Y", "Z", "yaw", "pitch", "roll", "psi_x", "psi_y")


@dataclass(frozen=True)
class SelectionSettings:
    """The selection's settings (module docstring): the look-angle coefficients up to degree `look_degree`
    and the exterior ones up to `exterior_degree` are candidates; a coefficient is insignificant below
    |x| / sigma_x = `significance`; fixing it may raise a control RMS by `max_increase` (a fraction), and
    `systematic` is the t-test's threshold as a normal quantile; `test_exterior`: run steps 2 and 3;
    `variance_components`: estimate the groups' sigmas first (variance.estimate)."""

    look_degree: int = 3
    exterior_degree: int = 3
    significance: float = 3.0
    max_increase: float = 0.10
    systematic: float = 3.0
    test_exterior: bool = True
    variance_components: bool = True


@dataclass
class Selection:
    """Result of `select_parameters`: the final adjustment (its `parameters.free` is the chosen
    set; the models carry its solution) and the log of every decision."""

    result: Adjustment
    free: list[str]  # names of the chosen free unknowns
    observations: Observations  # the observations adjusted (sigmas from variance components)
    components: list[Component]  # variance.Component of each group ([] without variance components)
    log: list[str] = field(default_factory=list)


@dataclass
class _ControlState:
    """Control point residuals of an adjustment: image RMS and |t| of the mean per image and
    component (col, row), ground RMS per E/N/H."""

    image_rms: dict
    image_t: dict
    ground_rms: np.ndarray
    image_sigma: dict  # a priori sigma (RMS) of the control image measurements per image
    ground_sigma: np.ndarray  # and of the control ground coordinates, E/N/H
    image_count: dict  # control measurements per image
    ground_count: int  # control points

    @classmethod
    def of(cls, result):
        obs = result.observations
        control = obs.points["role"] == "control"
        meas = control[obs.measurements["point"]]
        rms, t, sig, count = {}, {}, {}, {}
        for i in np.unique(obs.measurements["image_id"][meas]):
            sel = meas & (obs.measurements["image_id"] == i)
            v = result.residuals[sel]
            count[int(i)] = len(v)
            rms[int(i)] = float(np.sqrt(np.mean(v * v)))
            sig[int(i)] = float(np.sqrt(np.mean(obs.measurements["sigma"][sel] ** 2)))
            n = len(v)
            sd = v.std(axis=0, ddof=1) if n > 1 else np.full(2, np.inf)
            t[int(i)] = np.abs(v.mean(axis=0)) / np.where(sd > 0, sd / np.sqrt(n), np.inf)
        g = result.ground_residuals[control]
        gs = np.column_stack([obs.points[k][control] for k in ("sigma_e", "sigma_n", "sigma_h")])
        if not len(g):
            return cls(rms, t, np.zeros(3), sig, np.zeros(3), count, 0)
        return cls(rms, t, np.sqrt(np.mean(g * g, axis=0)), sig, np.sqrt(np.mean(gs * gs, axis=0)), count, len(g))

    def worse(self, new, max_increase, systematic, significance, names):
        """Reason why `new` (after fixing) is worse than self, or "" when it is not (module docstring)."""

        def grown(old, now, sigma, m):
            return now > old * (1.0 + max_increase) and m * (now * now - old * old) > (significance * sigma) ** 2

        for i, rms in self.image_rms.items():
            if grown(rms, new.image_rms.get(i, rms), self.image_sigma[i], 2 * self.image_count[i]):
                return (
                    f"the control residuals in {names.get(i, i)} grow from {rms:.3f} to {new.image_rms[i]:.3f} px RMS"
                )
            threshold = t_threshold(systematic, self.image_count[i])
            for k, axis in enumerate(("col", "row")):
                tn = new.image_t.get(i, self.image_t[i])[k]
                if tn > threshold >= self.image_t[i][k]:
                    return (
                        f"the control residuals in {names.get(i, i)} become systematic in {axis} "
                        f"(mean / its sigma {tn:.1f})"
                    )
        for k, axis in enumerate("ENH"):
            if grown(self.ground_rms[k], new.ground_rms[k], self.ground_sigma[k], self.ground_count):
                return (
                    f"the control ground residuals in {axis} grow from {self.ground_rms[k]:.3f} to "
                    f"{new.ground_rms[k]:.3f} m RMS"
                )
        return ""


def t_threshold(normal_quantile: float, n: int) -> float:
    """The threshold of |mean| / its sigma over n values (Student's t, n - 1 degrees of freedom) at the
    two-sided alpha of `normal_quantile` for a normal variable; inf for fewer than two values."""
    if n < 2:
        return float("inf")
    return float(stdtrit(n - 1, ndtr(normal_quantile)))


def _parameter(params, name):
    return params.parameters[params.select([name]).argmax()]


def _kind(params, name):
    return _parameter(params, name).kind


def _fix_key(params, name):
    p = _parameter(params, name)
    return (-p.degree, FIX_ORDER.index(p.kind) if p.kind in FIX_ORDER else len(FIX_ORDER))


def _highest_degrees(params, free):
    """The names in `free` that may be fixed next (module docstring): of a look-angle polynomial (owner,
    kind) the highest free degree, any other coefficient."""
    found = [(n, _parameter(params, n)) for n in free]
    top = {}
    for _, p in found:
        top[p.owner, p.kind] = max(top.get((p.owner, p.kind), -1), p.degree)
    return {n for n, p in found if p.kind not in LOOK or p.degree == top[p.owner, p.kind]}


def _solvable(run, free, fixable, log, what):
    """Adjust with `free`, fixing members of `fixable` that defects name until the block solves."""
    free = list(free)
    while True:
        try:
            return run(free), free
        except DefectError as error:
            drop = []
            for group in error.groups:
                candidates = [n for n in group if n in fixable and n in free and n not in drop]
                if not candidates:
                    raise
                drop.append(min(candidates, key=lambda n: _fix_key(run.base, n)))
            for name in drop:
                free.remove(name)
                log(f"{what}: fixed {name}: the points cannot determine it together with the other free unknowns")


def _eliminate(
    run: Restart,
    result: Adjustment,
    free: list[str],
    fixable: set[str],
    settings: SelectionSettings,
    log: Callable[[str], None],
    what: str,
    report: Callable[[float], Any],
) -> tuple[Adjustment, list[str]]:
    """Backward elimination of insignificant members of `fixable` (module docstring, with the thresholds of
    `settings`); report(fraction) after each trial (at most one trial per member)."""
    significance = settings.significance
    kept: set[str] = set()
    state = _ControlState.of(result)
    trials = 0
    while True:
        report(min(trials / max(len(fixable), 1), 1.0))
        trials += 1
        params = result.parameters
        t = {params.label(q): abs(result.values[q]) / result.sigmas[q] for q in np.flatnonzero(params.free)}
        top = _highest_degrees(params, free)
        trial = sorted((t[n], n) for n in free if n in fixable and n not in kept and n in top and t[n] < significance)
        if not trial:
            return result, free
        ratio, name = trial[0]
        reduced = [n for n in free if n != name]
        try:
            candidate = run(reduced)
        except DefectError:
            kept.add(name)
            log(f"{what}: kept {name} (x/sigma {ratio:.1f}): the block cannot be solved without it")
            continue
        new_state = _ControlState.of(candidate)
        reason = state.worse(new_state, settings.max_increase, settings.systematic, significance, run.names or {})
        if reason:
            kept.add(name)
            log(f"{what}: kept {name} (x/sigma {ratio:.1f}): fixing it, {reason}")
            continue
        log(f"{what}: fixed {name} (x/sigma {ratio:.1f}); sigma_0 {result.sigma0:.4f} -> {candidate.sigma0:.4f}")
        result, free, state = candidate, reduced, new_state


def select_parameters(
    models: dict[int, Any],
    observations: Observations,
    names: dict[int, str] | None = None,
    height: float = 0.0,
    selection: SelectionSettings | None = None,
    adjustment: AdjustmentSettings | None = None,
    feedback: Feedback | None = None,
) -> Selection:
    """Automatic parameter selection (module docstring) with SelectionSettings `selection`. models
    {image_id: model} (edited in place: they carry the final solution); observations, names, height and
    the AdjustmentSettings `adjustment` (priors, max_iterations, ...) as bundle.adjust (the trials leave
    out the image effects and test defects with SELECTION_DEFECT_EIGENVALUE). With
    `selection.variance_components`, the sigmas of the tie point, control image and control ground
    observations are first estimated (variance.estimate) with all step-1 candidates free and used
    throughout. Returns a Selection; raises what adjust raises (a DefectError when even the look-angle
    constants cannot be determined)."""
    settings = selection or SelectionSettings()
    adjustment = adjustment or AdjustmentSettings()
    if adjustment.model != "polynomial":
        raise InputError(
            "automatic parameter selection (Kornus et al. 2006, section 3.4.3) is for the correction "
            "polynomial model; with the Lagrange model give the free set (e.g. lagrange:attitude, "
            "lagrange:offset)"
        )
    fb = progress.ensure(feedback)
    lines: list[str] = []

    def log(text: str) -> None:
        lines.append(text)
        fb.pushInfo(text)

    run = Restart(
        models,
        observations,
        names,
        feedback,
        height=height,
        settings=replace(adjustment, effects=False, defect_eigenvalue=SELECTION_DEFECT_EIGENVALUE),
    )

    def phase(start: float, stop: float) -> Callable[[float], Any]:
        """report(fraction) of a phase spanning start..stop % (cancelling checked there too)."""
        return lambda fraction: progress.step(feedback, start + (stop - start) * fraction)

    params = run.base
    look = [
        p.name
        for p in params.parameters
        if (p.kind in LOOK and p.degree <= settings.look_degree) or p.kind not in LOOK + EXTERIOR
    ]
    log(
        f"parameter selection, step 1: {len(look)} look-angle/bias coefficients free, exterior ones fixed; "
        f"significance threshold x/sigma {settings.significance:g}"
    )
    result, free = _solvable(run, look, set(look), log, "step 1")
    components = []
    if settings.variance_components:
        result, run.observations, components = estimate(
            lambda o: run(free, o), run.observations, log=log, report=phase(0, 10)
        )
        log(
            "a posteriori sigmas used from here on: "
            + ", ".join(f"{c.group} {c.sigma:.3g}" for c in components if np.isfinite(c.sigma))
        )
    progress.step(feedback, 10)
    result, free = _eliminate(run, result, free, set(look), settings, log, "step 1", phase(10, 40))
    log(f"step 1: {len(free)} coefficient(s) free: {', '.join(free) or 'none'}")
    exterior = [p.name for p in params.parameters if p.kind in EXTERIOR and p.degree <= settings.exterior_degree]
    if settings.test_exterior and exterior:
        chosen = list(free)
        for part, kinds, pct, end in (("attitude", EXTERIOR[3:], 40, 70), ("position", EXTERIOR[:3], 70, 90)):
            candidates = [n for n in exterior if _kind(params, n) in kinds]
            progress.step(feedback, pct)
            log(f"step 2 ({part}): testing {len(candidates)} coefficients with the {len(free)} chosen so far free")
            try:
                result, free = _solvable(run, free + candidates, set(candidates), log, f"step 2 ({part})")
            except DefectError as error:
                log(f"step 2 ({part}): not tested, the block cannot be solved with them: {error}")
                continue
            result, free = _eliminate(
                run, result, free, set(candidates), settings, log, f"step 2 ({part})", phase(pct, end)
            )
        added = [n for n in free if n not in chosen]
        log(f"step 2: {len(added)} exterior coefficient(s) significant: {', '.join(added) or 'none'}")
        if added:
            progress.step(feedback, 90)
            result, free = _eliminate(run, result, free, set(chosen), settings, log, "step 3", phase(90, 99))
    # the models carry the last trial's solution: adjust the chosen set again
    result = run(free, settings=replace(run.settings, effects=True))
    progress.step(feedback, 100)
    log(f"selected {len(free)} free coefficient(s) in {run.count} adjustments: {', '.join(free) or 'none'}")
    return Selection(result, free, run.observations, components, lines)
