"""The points per group of a matching run, as Kornus et al. 2006, Table 1 gives them: rows for the log and a
CSV (three_combinations.py defines the groups)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Callable, Union

import numpy as np

from ..atomic import write_text
from .match_stats import MatchStats
from .points import MultiPoints

#: the summary: (label, count or figure) rows
Rows = list[tuple[str, Union[int, float]]]


def summary_rows(
    points: MultiPoints | Sequence[MultiPoints | Callable[[], MultiPoints]],
    rho_dem: float = 0.7,
    stats: MatchStats | None = None,
) -> Rows:
    """Counts per group like Kornus et al. 2006, Table 1: a list of (label, value). `points` is a
    MultiPoints, or a list of parts (MultiPoints, or functions returning one, taken one at a time) with
    the run's `stats`."""
    parts = [points] if isinstance(points, MultiPoints) else points
    if stats is None:
        stats = MatchStats.from_dict(points.stats if isinstance(points, MultiPoints) else None)
    counts = np.zeros(7, np.int64)
    for part in parts:
        p = (part if isinstance(part, MultiPoints) else part()).points
        g1, g2, g3 = (p["group"] == 1), (p["group"] == 2), (p["group"] == 3)
        high = p["rho_min"] > rho_dem
        counts += [g1.sum(), (g1 & high).sum(), g2.sum(), (g2 & high).sum(), g3.sum(), ((g2 | g3) & high).sum(), len(p)]
    n1, n1_high, n2, n2_high, n3, n23_high, total = (int(c) for c in counts)
    rows = [
        ("Two-ray points (group 1)", n1),
        (f"Two-ray points with rho > {rho_dem:g}", n1_high),
        ("Three-ray points matched in 2 combinations (group 2)", n2),
        (f"Three-ray points in 2 combinations with rho > {rho_dem:g}", n2_high),
        ("Points matched in 3 combinations", n3 if stats.matched_3 is None else stats.matched_3),
        (f"Points in 3 combinations with |d| < {stats.sigma_factor or 3.0:g} sigma (group 3)", n3),
        (f"Three-ray points selected for DEM generation (rho > {rho_dem:g})", n23_high),
        ("All points", total),
    ]
    for sigma, label in [(stats.sigma_dx, "sigma of dx (px, robust)"), (stats.sigma_dy, "sigma of dy (px, robust)")]:
        if sigma is not None:
            rows.append((label, round(float(sigma), 4)))
    if stats.refined_mpgc is not None:
        rows.append(("Group 3 points refined by MPGC", int(stats.refined_mpgc)))
    return rows


def format_summary(rows: Rows) -> str:
    """The summary rows as aligned text for the log."""
    width = max(len(label) for label, _ in rows)
    return "\n".join(
        f"{label:<{width}}  {value:>12}" if isinstance(value, int) else f"{label:<{width}}  {value:>12g}"
        for label, value in rows
    )


def write_summary_csv(path: str, rows: Rows) -> str:
    """Write the summary rows as CSV (item,value) atomically."""
    lines = ["item,value"] + [f'"{label}",{value}' for label, value in rows]
    write_text(path, "\n".join(lines) + "\n")
    return path
