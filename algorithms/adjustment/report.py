"""Text/HTML report of a bundle adjustment: the coefficient table of K Table 2 (value, sigma,
x/sigma, maximum effect in pixels over the image: parameters.max_effects), check point statistics
of K Table 3 (dE, dN, dH: n, min, mean, max, RMS, sigma, with the theoretical RMS), the removed
blunders and the count of measurements still flagged."""
import html

import numpy as np

from ..atomic import write_text
from .parameters import UNITS


def coefficient_rows(result):
    """(name, value, sigma, x/sigma, unit, maximum effect px) of the free unknowns, in display units."""
    rows = []
    for q in np.flatnonzero(result.parameters.free):
        p = result.parameters.parameters[q]
        unit, factor = UNITS.get(p.kind, ("px", 1.0))
        value, sigma = result.values[q] * factor, result.sigmas[q] * factor
        rows.append((p.name, value, sigma, abs(value) / sigma if sigma > 0 else float("inf"), unit,
                     result.effects[q]))
    return rows


def text_report(result, check=None, table=None, critical=3.29):
    """The report as plain text (also logged)."""
    lines = [f"sigma_0 = {result.sigma0:.4f} (a priori 1), redundancy {result.redundancy}, "
             f"{result.iterations} iteration(s)", "", "free orientation parameters:",
             f"{'parameter':32} {'value':>12} {'sigma':>10} {'x/sigma':>8} {'unit':>5} {'max. effect px':>15}"]
    lines += [f"{n:32} {v:12.4f} {s:10.4f} {t:8.1f} {u:>5} {e:15.3f}" for n, v, s, t, u, e in coefficient_rows(result)]
    if result.removed:
        lines += ["", "measurements removed by data snooping (point, image id, |w|):"]
        lines += [f"  {n} in image {i}: {w:.1f}" for n, i, w in result.removed]
    flagged = result.flagged(critical)
    lines += ["", f"{len(flagged)} measurement(s) with |w| > {critical:g} left in the adjustment"]
    if table:
        lines += ["", "check points (m, computed - reference):",
                  f"{'':4} {'n':>4} {'min':>8} {'mean':>8} {'max':>8} {'RMS':>8} {'sigma':>8} {'theor.':>8}"]
        theoretical = np.sqrt(np.mean(check["sigma"] ** 2, axis=0)) if len(check["dE"]) else [np.nan] * 3
        for k, key in enumerate(("dE", "dN", "dH")):
            n, lo, mean, hi, rms, sd = table[key]
            lines.append(f"{key:4} {n:4d} {lo:8.3f} {mean:8.3f} {hi:8.3f} {rms:8.3f} {sd:8.3f} {theoretical[k]:8.3f}")
    return "\n".join(lines)


def write_html(path, title, text):
    """A self-contained HTML page holding the text report."""
    write_text(path, f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
                     f"</head><body><h1>{html.escape(title)}</h1><pre>{html.escape(text)}</pre></body></html>\n")
    return path
