"""Figures of height differences as PNG bytes, drawn with matplotlib's Agg canvas (no display, no
pyplot state): histograms of dh per group or class (Kornus et al. 2006, Figs. 4, 7) and a colour-coded dh map
(Kornus et al. 2006, Fig. 5) with a diverging colormap centred on 0 and symmetric limits +-Q95(|dh|), drawn
from an assessment.Summary (statistics.DhSummary histograms, its map grid or thinned points)."""

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from ..histogram import quantile
from .statistics import DhSummary

CMAP = "RdBu_r"
BINS = 60


def _png(fig):
    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def map_limit(summary):
    """The symmetric colour limit of the dh map: Q95 of |dh| of the DhSummary `summary` (1 m where that is 0
    or there is none)."""
    limit = summary.stats().q95 if summary.n else 0.0
    return limit if limit > 0 else 1.0


def histogram(series, title):
    """PNG of the dh histograms of `series` [(label, DhSummary)] as relative frequencies (%) over common
    bins spanning the 0.5-99.5 % quantiles of all values."""
    everything = DhSummary()
    for _, summary in series:
        everything = everything.merge(summary)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    if everything.n:
        values, counts = everything.values()
        lo, hi = (quantile(values, counts, q) for q in (0.005, 0.995))
        edges = np.linspace(lo, hi, BINS + 1) if hi > lo else np.linspace(lo - 1, lo + 1, BINS + 1)
        for label, summary in series:
            values, counts = summary.values()
            ax.hist(
                values,
                edges,
                weights=100.0 * counts / summary.n,
                histtype="step",
                linewidth=1.5,
                label=f"{label} (N = {summary.n})",
            )
        ax.legend(fontsize=8)
    ax.axvline(0.0, color="0.5", linewidth=0.8)
    ax.set_xlabel("dh [m]")
    ax.set_ylabel("frequency [%]")
    ax.set_title(title)
    fig.tight_layout()
    return _png(fig)


def dh_map(summary, title):
    """PNG of the dh map of `summary` (assessment.Summary): its grid for a DEM, its points coloured
    otherwise; RdBu_r centred on 0, limits +-map_limit."""
    limit = map_limit(summary.all)
    norm = Normalize(-limit, limit)
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot()
    if summary.map_grid is not None:
        x0, dx, _, y0, _, dy = summary.map_grid.geotransform
        rows, cols = summary.map_grid.shape
        image = ax.imshow(
            summary.map_grid.values,
            cmap=CMAP,
            norm=norm,
            interpolation="nearest",
            extent=(x0, x0 + cols * dx, y0 + rows * dy, y0),
        )
    else:
        x, y, dh = summary.map_points
        order = np.argsort(np.abs(dh))  # large |dh| drawn last, on top
        image = ax.scatter(x[order], y[order], c=dh[order], cmap=CMAP, norm=norm, s=2, linewidths=0)
        ax.set_aspect("equal")
    ax.set_facecolor("0.15")
    fig.colorbar(image, ax=ax, label="dh [m]", extend="both")
    unit = "deg" if summary.srs.IsGeographic() else "m"
    ax.set_xlabel(f"x [{unit}] ({summary.srs.GetName()})")
    ax.set_ylabel(f"y [{unit}]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_title(title)
    fig.tight_layout()
    return _png(fig)
