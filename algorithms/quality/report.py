"""Tables, log text, CSV and the self-contained HTML report of an accuracy assessment.

Tables mirror the papers: Kornus et al. 2006, Tables 4, 6, 7 (N, Min, Mean, Max, RMS, sigma of dh; per point group
as Table 6, groups 3, 2, 1), with the robust extras NMAD and Q95(|dh|) (statistics.py) as last
columns, and Zhang and Gruen 2004, Tables 2-3 (area, number of compared points, mean, RMSE, % of |dh| < 2 m, 2-5 m,
> 5 m) over nested class sets (statistics.cumulative). The HTML page embeds its figures as base64
PNG (figures.py): it references no other file."""

import base64
import csv
import html
import io
from dataclasses import dataclass
from typing import Any

from ..adjustment.report import Section, html_sections, render_text
from ..atomic import write_text
from . import figures
from .coregister_dem import sections as shift_sections
from .statistics import by_label, cumulative

GROUP_NAMES = {
    3: "Point group 3: three-ray points from 3 matching runs",
    2: "Point group 2: three-ray points from 2 matching runs",
    1: "Point group 1: two-ray points",
}
K_HEADER = ("", "N", "Min", "Mean", "Max", "RMS", "sigma", "NMAD", "Q95 |dh|")
Z_HEADER = ("Area", "No. of compared points", "Mean (m)", "RMSE (m)", "< 2.0 m", "2.0-5.0 m", "> 5.0 m")
CSV_HEADER = (
    "data",
    "table",
    "label",
    "n",
    "min",
    "mean",
    "max",
    "rms",
    "sigma",
    "median",
    "nmad",
    "q95_abs",
    "pct_below_2m",
    "pct_2_to_5m",
    "pct_above_5m",
)


def _k_row(label, s):
    return (label, str(s.n), *(f"{v:.2f}" for v in (s.min, s.mean, s.max, s.rms, s.sigma, s.nmad, s.q95)))


def _z_row(label, s):
    return (label, str(s.n), f"{s.mean:.2f}", f"{s.rms:.2f}", *(f"{p:.1f}%" for p in s.shares))


def tables(summary):
    """[(table name, [(label, Stats)], form "K" or "Z")] of one assessment.Summary."""
    out = [("all (Kornus et al. 2006, Table 4)", [("dh", summary.all.stats())], "K")]
    if summary.groups is not None:
        out.append(("per point group (Kornus et al. 2006, Tables 6, 7)", by_label(summary.groups, GROUP_NAMES), "K"))
    if summary.classes is not None:
        out.append(("per class", by_label(summary.classes, summary.class_names), "K"))
        out.append(
            ("nested classes (Zhang and Gruen 2004, Tables 2-3)", cumulative(summary.classes, summary.class_names), "Z")
        )
    out.append(
        (
            "flat/moderate vs mountainous (Kornus et al. 2006, section 3.7)",
            by_label(summary.terrain, summary.terrain_names),
            "K",
        )
    )
    return out


@dataclass(frozen=True)
class Comparison:
    """A DEM's co-registration (coregistration.CoregResult) and its assessment.Summary before and after it, against
    the height_differences.Reference `reference`."""

    result: Any
    before: Any
    after: Any
    reference: Any


#: the statistics the before-and-after table sets side by side
COMPARED = (("mean", "Mean"), ("rms", "RMS"), ("nmad", "NMAD"), ("median", "median"))


def comparison_sections(comparison):
    """The co-registration's shift, then every table of the DEM's with its statistics before and after side by
    side (N, then COMPARED, each before | after)."""
    parts = shift_sections(comparison.result, comparison.before.source, comparison.reference)[:2]
    header = ("", "N before", "N after", *(f"{name} {when}" for _, name in COMPARED for when in ("before", "after")))
    after = {name: dict(rows) for name, rows, _ in tables(comparison.after)}
    for name, rows, form in tables(comparison.before):
        if form != "K":
            continue
        pairs = [(label, s, after.get(name, {}).get(label)) for label, s in rows]
        parts.append(
            Section(
                f"dh [m] of the DEM cells - reference, before and after co-registration: {name}",
                header,
                [
                    (
                        label,
                        str(b.n),
                        str(a.n) if a else "-",
                        *(f"{getattr(s, key):.2f}" if s else "-" for key, _ in COMPARED for s in (b, a)),
                    )
                    for label, b, a in pairs
                ],
            )
        )
    return parts


def sections(summaries, parameters=(), comparison=None):
    """Report Sections: the inputs and parameters [(name, value)], the before-and-after tables of a co-registered
    DEM (a Comparison, or None), then every table of every input (assessment.Summary)."""
    parts = [Section("Inputs and parameters", ("parameter", "value"), [(str(k), str(v)) for k, v in parameters])]
    if comparison is not None:
        parts += comparison_sections(comparison)
    for a in summaries:
        for name, rows, form in tables(a):
            header, cell = (K_HEADER, _k_row) if form == "K" else (Z_HEADER, _z_row)
            parts.append(
                Section(f"dh [m] of the {a.what} - reference: {name}", header, [cell(label, s) for label, s in rows])
            )
        parts[-1].notes.append(
            f"{a.what} of {a.source}: {a.all.n} compared; left out: "
            + ", ".join(f"{reason} {n}" for reason, n in a.excluded.items())
        )
    return parts


def text(summaries, parameters=(), comparison=None):
    """The report's tables as plain text (the log)."""
    return render_text(sections(summaries, parameters, comparison))


def write_csv(path, summaries):
    """Every table row with every statistic (CSV_HEADER), written atomically."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(CSV_HEADER)
    for a in summaries:
        for name, rows, _ in tables(a):
            for label, s in rows:
                writer.writerow(
                    [
                        a.what,
                        name,
                        label,
                        s.n,
                        *(
                            f"{v:.4f}"
                            for v in (s.min, s.mean, s.max, s.rms, s.sigma, s.median, s.nmad, s.q95, *s.shares)
                        ),
                    ]
                )
    write_text(path, buffer.getvalue())
    return str(path)


def figure_list(summaries):
    """[(caption, PNG bytes)]: per input the dh map and histograms per point group, class and terrain."""
    out = []
    for a in summaries:
        every = (
            f"; every {a.map_step}th {'cell of each row and column' if a.map_grid is not None else 'point'}"
            if a.map_step > 1
            else ""
        )
        out.append(
            (
                f"dh of the {a.what} (colour limits +-Q95 |dh| = {figures.map_limit(a.all):.2f} m{every})",
                figures.dh_map(a, f"dh of the {a.what}"),
            )
        )
        splits = [
            ("point group", a.groups, GROUP_NAMES),
            ("class", a.classes, a.class_names),
            ("terrain", a.terrain, a.terrain_names),
        ]
        for kind, labelled, names in splits:
            if labelled is not None:
                series = [
                    (name, labelled[value]) for value, name in names.items() if value in labelled and labelled[value].n
                ]
                out.append(
                    (
                        f"Histogram of dh of the {a.what} per {kind}",
                        figures.histogram(series, f"dh of the {a.what} per {kind}"),
                    )
                )
    return out


def write_report(path, title, summaries, parameters=(), comparison=None):
    """One self-contained HTML page: the Sections' tables and the figures as embedded PNGs."""
    style = (
        "body{font-family:sans-serif}table{border-collapse:collapse}th,td{border:1px solid #bbb;"
        "padding:2px 8px;text-align:right}th:first-child,td:first-child{text-align:left}"
    )
    images = "\n".join(
        f"<figure><img alt='{html.escape(caption)}' src='data:image/png;base64,"
        f"{base64.b64encode(png).decode('ascii')}'><figcaption>{html.escape(caption)}</figcaption>"
        "</figure>"
        for caption, png in figure_list(summaries)
    )
    write_text(
        path,
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{style}</style></head><body><h1>{html.escape(title)}</h1>\n"
        f"{html_sections(sections(summaries, parameters, comparison))}\n<h2>Figures</h2>\n{images}\n"
        "</body></html>\n",
    )
    return str(path)
