"""Check point accuracy against the number of control points (Heipke et al. 1992, section 4.1.2, Table 1).

The candidates are the observations' control points; the check and tie points stay the same in
every row. For each count n the block is adjusted (bundle.adjust, on a copy of the models) with n
control points chosen by farthest-point sampling in local metres east/north: first the candidate
farthest from the candidates' centroid, then each time the one whose distance to the nearest
chosen point is largest (ties: the first in the observations). The sets are nested (the n-point
set holds the (n-1)-point one): four corners and the centre on an even spread, then the edges.
Candidates not chosen take no part (neither control nor check). The check points are intersected
with the adjusted models (bundle.check_points); a row gives the RMS of their dE, dN, dH, the RMS
of their theoretical sigmas and sigma_0."""

from __future__ import annotations

import copy
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import progress
from ..errors import InputError
from ..geodesy import metres_per_degree
from ..progress import Feedback
from ..stats import statistics_table
from .bundle import AdjustmentSettings, adjust, check_points
from .observations import Observations


@dataclass
class SeriesRow:
    """One adjustment of the series."""

    control: tuple  # names of its control points
    check: int  # check points intersected
    rms: np.ndarray  # (3,) RMS of dE, dN, dH (m)
    theoretical: np.ndarray  # (3,) RMS of their theoretical sigmas E, N, H (m)
    sigma0: float
    redundancy: int


def farthest_points(lon, lat, count):
    """Indices of `count` well-distributed points (module docstring), in the order chosen."""
    lon, lat = np.asarray(lon, float), np.asarray(lat, float)
    if not 0 < count <= lon.size:
        raise InputError(f"cannot choose {count} control points from {lon.size} candidates")
    e_deg, n_deg = metres_per_degree(lat.mean())
    xy = np.column_stack([(lon - lon.mean()) * e_deg, (lat - lat.mean()) * n_deg])
    chosen = [int(np.argmax(np.hypot(*xy.T)))]
    nearest = np.hypot(*(xy - xy[chosen[0]]).T)
    while len(chosen) < count:
        q = int(np.argmax(nearest))
        chosen.append(q)
        nearest = np.minimum(nearest, np.hypot(*(xy - xy[q]).T))
    return np.array(chosen)


def control_point_series(
    models: dict[int, Any],
    observations: Observations,
    counts: Iterable[int],
    free: list[str],
    names: dict[int, str] | None = None,
    height: float = 0.0,
    settings: AdjustmentSettings | None = None,
    feedback: Feedback | None = None,
) -> list[SeriesRow]:
    """SeriesRows for each control point count in `counts` (module docstring). models: {image_id:
    model} (not edited: each row adjusts a copy); observations: the candidates as control points,
    the check and tie points; free, names, height and `settings` (AdjustmentSettings: model, priors, ...)
    as bundle.adjust. Raises InputError (a count above the candidates, no check point) and what
    adjust raises; CancelledError when cancelled."""
    obs = observations.check()
    roles = obs.points["role"]
    candidates = np.flatnonzero(roles == "control")
    if not (roles == "check").any():
        raise InputError("the control point series needs check points: give some points the role 'check'")
    counts = sorted(set(int(n) for n in counts))
    if not counts or counts[0] < 1 or counts[-1] > candidates.size:
        raise InputError(f"control point counts {counts} must lie within 1..{candidates.size} (the candidates)")
    order = candidates[farthest_points(obs.points["lon"][candidates], obs.points["lat"][candidates], counts[-1])]
    rows = []
    for k, n in enumerate(counts):
        progress.step(feedback, 100.0 * k / len(counts), f"control point series: {n} control points")
        keep = roles != "control"
        keep[order[:n]] = True
        used = obs.subset(keep)
        result = adjust(
            copy.deepcopy(models),
            used,
            free,
            names=names,
            height=height,
            settings=settings,
            feedback=progress.scaled(feedback, 100.0 * k / len(counts), 100.0 * (k + 1) / len(counts)),
        )
        check = check_points(result, used, height)
        table = statistics_table({key: check[key] for key in ("dE", "dN", "dH")})
        rows.append(
            SeriesRow(
                control=tuple(str(s) for s in obs.points["name"][order[:n]]),
                check=len(check["dE"]),
                rms=np.array([table[key][4] for key in ("dE", "dN", "dH")]),
                theoretical=np.sqrt(np.mean(check["sigma"] ** 2, axis=0)),
                sigma0=result.sigma0,
                redundancy=result.redundancy,
            )
        )
    progress.step(feedback, 100.0)
    return rows
