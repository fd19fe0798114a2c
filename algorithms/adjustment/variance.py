"""Variance component estimation for the bundle adjustment (Foerstner 1979; Koch, Parameter
Estimation, section 3.6): one unknown variance factor per group of observations, here the image
coordinates of tie points, the image coordinates of control points and the ground coordinates of
control points. With the redundancy numbers r_i of the adjustment, the group's factor is

    s_g^2 = sum_g p_i v_i^2 / sum_g r_i,

and its a priori sigmas are multiplied by s_g; repeated until every s_g is within `tolerance` of
1. A group whose redundancy is below MIN_REDUNDANCY, or whose residuals are all zero (s_g = 0 would
give it infinite weight), keeps its sigmas. Matched tie points are often far more precise than the
0.5 px a priori (0.1-0.2 px), so without this sigma_0 mixes the groups and the control-determined
unknowns get sigmas (and significances) off by the ratio of the groups' factors."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import progress
from ..progress import Feedback
from .bundle import Adjustment, AdjustmentSettings, Restart
from .observations import Observations

GROUPS = ("tie image", "control image", "control ground")
#: a group needs at least this redundancy for its factor to be estimated (else it keeps its sigmas)
MIN_REDUNDANCY = 5.0


@dataclass
class Component:
    group: str
    count: int  # observations (coordinates) in the group
    redundancy: float  # sum of the group's redundancy numbers
    factor: float  # s_g of the last adjustment (NaN: not estimated)
    sigma: float  # the group's resulting a priori sigma (RMS over the group; px or m)


def group_factors(result):
    """{group: (count, redundancy, s_g)} of an Adjustment (s_g NaN where the redundancy is too small)."""
    obs = result.observations
    role = obs.points["role"][obs.measurements["point"]]
    w = 1.0 / obs.measurements["sigma"] ** 2
    out = {}
    for group, sel in (("tie image", role == "tie"), ("control image", role == "control")):
        v, r = result.residuals[sel], result.redundancy_numbers[sel]
        out[group] = _factor(2 * int(sel.sum()), float(np.sum(r)), float(np.sum(w[sel, None] * v * v)))
    control = obs.points["role"] == "control"
    sig = np.column_stack([obs.points["sigma_e"], obs.points["sigma_n"], obs.points["sigma_h"]])[control]
    qpp = (result.point_sigmas[control] / result.sigma0) ** 2 if result.sigma0 > 0 else np.zeros((control.sum(), 3))
    red = 1.0 - qpp / sig**2
    v = result.ground_residuals[control]
    out["control ground"] = _factor(v.size, float(np.sum(red)), float(np.sum(v * v / sig**2)))
    return out


def _factor(count, redundancy, vpv):
    ok = count and redundancy >= MIN_REDUNDANCY and np.isfinite(vpv) and vpv > 0.0
    return count, redundancy, float(np.sqrt(vpv / redundancy)) if ok else float("nan")


def rescaled(observations, factors):
    """Copy of `observations` with each group's sigmas multiplied by its factor (NaN: unchanged).
    Check points are measured like control points: they take the control groups' factors."""
    p, m = observations.points.copy(), observations.measurements.copy()
    role = p["role"][m["point"]]
    for group, sel in (("tie image", role == "tie"), ("control image", role != "tie")):
        if np.isfinite(factors.get(group, np.nan)):
            m["sigma"][sel] *= factors[group]
    f = factors.get("control ground", np.nan)
    if np.isfinite(f):
        ground = p["role"] != "tie"
        for key in ("sigma_e", "sigma_n", "sigma_h"):
            p[key][ground] *= f
    return Observations(p, m)


def estimate(run, observations, max_rounds=6, tolerance=0.05, log=None, report=None):
    """Iterate `run(observations) -> Adjustment` with rescaled sigmas until every group factor is
    within `tolerance` of 1 (at most `max_rounds` adjustments; report(fraction) before each). Returns (the
    last Adjustment, the rescaled observations, [Component])."""
    obs = observations
    for round_ in range(1, max_rounds + 1):
        if report:
            report((round_ - 1) / max_rounds)
        result = run(obs)
        factors = group_factors(result)
        change = {g: f for g, (_, _, f) in factors.items() if np.isfinite(f)}
        if log:
            log(f"variance components, round {round_}: " + ", ".join(f"{g} x {f:.3f}" for g, f in change.items()))
        if all(abs(f - 1.0) <= tolerance for f in change.values()):
            break
        if round_ == max_rounds:
            if log:
                log(f"variance components not converged in {max_rounds} rounds: the last factors are used as they are")
            break
        obs = rescaled(obs, change)
    components = []
    for g, (count, red, f) in factors.items():
        components.append(Component(g, count, red, f, float(_group_sigma(obs, g)) if count else float("nan")))
    return result, obs, components


def adjust_with_components(
    models: dict[int, Any],
    observations: Observations,
    free: list[str],
    names: dict[int, str] | None = None,
    height: float = 0.0,
    settings: AdjustmentSettings | None = None,
    feedback: Feedback | None = None,
) -> tuple[Adjustment, Observations, list[Component]]:
    """bundle.adjust (with `height` and `settings`) with variance component estimation: each round starts
    again from the models' current orientation (so priors and fixed parameters keep their meaning). Returns
    (Adjustment, the rescaled observations, [Component]); the models carry the last solution."""
    run = Restart(models, observations, names, feedback, height, settings)
    return estimate(
        lambda obs: run(free, obs),
        observations,
        log=progress.ensure(feedback).pushInfo,
        report=lambda fraction: progress.step(feedback, 100.0 * fraction),
    )


def _group_sigma(obs, group):
    role = obs.points["role"][obs.measurements["point"]]
    if group == "control ground":
        control = obs.points["role"] == "control"
        s = np.column_stack([obs.points["sigma_e"], obs.points["sigma_n"], obs.points["sigma_h"]])[control]
    else:
        s = obs.measurements["sigma"][role == group.split()[0]]
    return np.sqrt(np.mean(np.square(s))) if np.size(s) else np.nan
