"""Text/HTML report of a bundle adjustment, as Kornus et al. 2006, section 3.4.3 reports it: the coefficient table of
Kornus et al. 2006, Table 2 (value, sigma, x/sigma, maximum effect in pixels over the image: parameters.max_effects),
the check point statistics of Kornus et al. 2006, Table 3 (dE, dN, dH: n, min, mean, max, RMS, sigma, with the
theoretical RMS), the tie point heights against a reference DTM of Kornus et al. 2006, Table 4 (dh: n, min, mean,
max, RMS, sigma; tie_heights.py), the residuals per control/check point (residual_vectors.py),
the removed blunders and the count of measurements still flagged. A solution that did not converge
opens the report with an alert section (red in HTML) saying so. The same sections render as text
(the log) and as HTML tables (one self-contained page)."""

import html
from dataclasses import dataclass, field

import numpy as np

from ..atomic import write_text
from ..stats import statistics_table
from .bundle import CRITICAL_W
from .parameters import UNITS

STATISTICS = ("n", "min", "mean", "max", "RMS", "sigma")


@dataclass
class Section:
    """A titled table (header, rows of cell strings; the first column is a label) and note lines."""

    title: str
    header: tuple = ()
    rows: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    alert: bool = False  # shown first and prominently (a solution not to be used)


def coefficient_rows(result):
    """(name, value, sigma, x/sigma, unit, maximum effect px) of the free unknowns, in display units."""
    rows = []
    for q in np.flatnonzero(result.parameters.free):
        p = result.parameters.parameters[q]
        unit, factor = UNITS.get(p.kind, ("px", 1.0))
        value, sigma = result.values[q] * factor, result.sigmas[q] * factor
        rows.append((p.name, value, sigma, abs(value) / sigma if sigma > 0 else float("inf"), unit, result.effects[q]))
    return rows


def _statistics_cells(row):
    n, *values = row
    return [str(n)] + [f"{v:.3f}" for v in values]


def sections(result, check=None, table=None, critical=CRITICAL_W, heights=None, vectors=None):
    """The report's Sections. check: bundle.check_points; table: statistics_table of its dE, dN, dH;
    heights: (TieHeights, description of the reference); vectors: residual_vectors.residual_vectors."""
    state = "converged" if result.converged else "NOT converged"
    out = [
        Section(
            "Adjustment",
            notes=[
                f"sigma_0 = {result.sigma0:.4f} (a priori 1), redundancy "
                f"{result.redundancy}, {result.iterations} iteration(s), {state}",
                *result.notes,
            ],
        )
    ]
    if not result.converged:
        out.insert(
            0,
            Section(
                "Not converged: these results were not stored",
                alert=True,
                notes=[
                    f"The adjustment stopped after {result.iterations} iteration(s) with a last point update of "
                    f"{result.last_update:.3g} m: the values, sigmas and residuals below are those of its last "
                    "iteration, not of a least squares solution, and the block keeps its models. Raise the maximum "
                    "iterations; "
                    "if it still does not converge, free fewer parameters or check the control points."
                ],
            ),
        )
    out.append(
        Section(
            "Free orientation parameters (Kornus et al. 2006, Table 2)",
            ("parameter", "value", "sigma", "x/sigma", "unit", "max. effect px"),
            [(n, f"{v:.4f}", f"{s:.4f}", f"{t:.1f}", u, f"{e:.3f}") for n, v, s, t, u, e in coefficient_rows(result)],
        )
    )
    flagged = result.flagged(critical)
    out.append(
        Section(
            "Data snooping",
            ("removed measurement (point)", "image id", "|w|"),
            [(n, str(i), f"{w:.1f}") for n, i, w in result.removed],
            [
                f"{len(result.removed)} measurement(s) removed, {len(flagged)} with |w| > {critical:g} "
                "left in the adjustment"
            ],
        )
    )
    if table:
        theoretical = np.sqrt(np.mean(check["sigma"] ** 2, axis=0))
        out.append(
            Section(
                "Check points (Kornus et al. 2006, Table 3)",
                ("m",) + STATISTICS + ("theor. RMS",),
                [
                    (key, *_statistics_cells(table[key]), f"{theoretical[k]:.3f}")
                    for k, key in enumerate(("dE", "dN", "dH"))
                ],
                ["computed - reference; theor. RMS: RMS of the check points' theoretical sigmas"],
            )
        )
        if vectors is not None:
            bad = vectors["name"][(vectors["role"] == "check") & vectors["flagged"]]
            if bad.size:
                out[-1].notes.append(
                    f"included: {bad.size} check point(s) with |w| > {critical:g} in their "
                    f"intersection ({', '.join(bad)})"
                )
    if check is not None and check.get("left_out"):
        out.append(
            Section(
                "Check points left out",
                notes=[
                    f"{len(check['left_out'])} check point(s) cannot be intersected (fewer than two image measurements "
                    f"or parallel rays): {', '.join(map(str, check['left_out']))}"
                ],
            )
        )
    if heights is not None:
        tie, reference = heights
        out.append(
            Section(
                "Tie point heights against the reference DTM (Kornus et al. 2006, Table 4)",
                ("m",) + STATISTICS,
                [("dh", *_statistics_cells(statistics_table({"dh": tie.dh})["dh"]))],
                [f"adjusted - reference ({reference}); {tie.outside} tie point(s) outside the reference left out"],
            )
        )
    if vectors is not None and len(vectors):
        out.append(
            Section(
                "Residuals per control and check point",
                (
                    "point",
                    "role",
                    "dE m",
                    "dN m",
                    "dH m",
                    "sigma E",
                    "sigma N",
                    "sigma H",
                    "RMS px",
                    "max |w|",
                    "flagged",
                ),
                [
                    (
                        r["name"],
                        r["role"],
                        *(f"{r[k]:.3f}" for k in ("dE", "dN", "dH", "sigma_e", "sigma_n", "sigma_h", "rms_px")),
                        f"{r['max_w']:.2f}",
                        "yes" if r["flagged"] else "",
                    )
                    for r in vectors
                ],
                [
                    "control points: adjusted - observed, image residuals of the adjustment; check points: "
                    "intersected - reference, image residuals of their forward intersection"
                ],
            )
        )
    return out


def variance_section(components):
    """Section of the estimated variance components (variance.estimate)."""
    return Section(
        "Variance components",
        ("group", "observations", "redundancy", "last factor", "sigma"),
        [(c.group, str(c.count), f"{c.redundancy:.1f}", f"{c.factor:.3f}", f"{c.sigma:.4g}") for c in components],
        ["sigma: the group's a posteriori sigma (px; m for ground coordinates), used as its weight"],
    )


def series_section(rows):
    """Section of control_series.control_point_series (Heipke et al. 1992, Table 1)."""
    return Section(
        "Check points against the number of control points (Heipke et al. 1992, Table 1)",
        ("control points", "check points", "RMS dE", "RMS dN", "RMS dH", "theor. E", "theor. N", "theor. H", "sigma_0"),
        [
            (str(len(r.control)), str(r.check), *(f"{v:.3f}" for v in (*r.rms, *r.theoretical)), f"{r.sigma0:.3f}")
            for r in rows
        ],
        [
            "m; the same free parameters and check points in every row; control points chosen farthest "
            "apart (nested sets): " + "; ".join(f"{len(r.control)}: {', '.join(r.control)}" for r in rows[:1])
        ],
    )


def render_text(parts):
    """Sections as plain text: aligned columns, the first one left-aligned."""
    lines = []
    for s in parts:
        lines += ["", f"{s.title}:"]
        if s.rows:
            cells = [tuple(s.header)] + [tuple(r) for r in s.rows]
            widths = [max(len(str(c[k])) for c in cells) for k in range(len(s.header))]
            lines += [
                "  "
                + " ".join(str(c).ljust(w) if k == 0 else str(c).rjust(w) for k, (c, w) in enumerate(zip(row, widths)))
                for row in cells
            ]
        lines += [f"  {n}" for n in s.notes]
    return "\n".join(lines[1:])


def text_report(result, check=None, table=None, critical=CRITICAL_W, heights=None, vectors=None):
    """The report as plain text (also logged); arguments as `sections`."""
    return render_text(sections(result, check, table, critical, heights, vectors))


def html_sections(parts):
    """Sections as HTML (headings, tables, note paragraphs)."""
    body = []
    for s in parts:
        body.append(f"<h2 class='alert'>{html.escape(s.title)}</h2>" if s.alert else f"<h2>{html.escape(s.title)}</h2>")
        if s.rows:
            body.append("<table><tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in s.header) + "</tr>")
            body += ["<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in s.rows]
            body.append("</table>")
        body += [f"<p class='alert'>{html.escape(n)}</p>" if s.alert else f"<p>{html.escape(n)}</p>" for n in s.notes]
    return "\n".join(body)


def write_html(path, title, text="", parts=()):
    """A self-contained HTML page: the Sections `parts` as tables, then `text` preformatted."""
    style = (
        "body{font-family:sans-serif}table{border-collapse:collapse}th,td{border:1px solid #bbb;"
        "padding:2px 8px;text-align:right}th:first-child,td:first-child{text-align:left}"
        ".alert{color:#b00000;font-weight:bold}"
    )
    pre = f"<pre>{html.escape(text)}</pre>" if text else ""
    write_text(
        path,
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{style}</style></head><body><h1>{html.escape(title)}</h1>\n{html_sections(parts)}\n"
        f"{pre}</body></html>\n",
    )
    return path
