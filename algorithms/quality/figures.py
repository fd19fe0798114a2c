"""Figures of height differences as PNG bytes, drawn with matplotlib's Agg canvas (no display, no
pyplot state): histograms of dh per group or class (Kornus et al. 2006, Figs. 4, 7) and a colour-coded dh map
(Kornus et al. 2006, Fig. 5) with a diverging colormap centred on 0 and symmetric limits +-Q95(|dh|)."""
import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from .statistics import QUANTILE

CMAP = "RdBu_r"
BINS = 60


def _png(fig):
    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def map_limit(dh):
    """The symmetric colour limit of the dh map: Q95 of |dh| (1 m where that is 0)."""
    a = np.abs(np.asarray(dh, float))
    a = a[np.isfinite(a)]
    limit = float(np.quantile(a, QUANTILE)) if a.size else 0.0
    return limit if limit > 0 else 1.0


def histogram(series, title):
    """PNG of the dh histograms of `series` [(label, dh array)] as relative frequencies (%) over common
    bins spanning the 0.5-99.5 % quantiles of all values."""
    everything = np.concatenate([np.asarray(v, float) for _, v in series]) if series else np.zeros(0)
    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot()
    if everything.size:
        lo, hi = np.quantile(everything, [0.005, 0.995])
        edges = np.linspace(lo, hi, BINS + 1) if hi > lo else np.linspace(lo - 1, lo + 1, BINS + 1)
        for label, values in series:
            values = np.asarray(values, float)
            if values.size:
                ax.hist(values, edges, weights=np.full(values.size, 100.0 / values.size), histtype="step",
                        linewidth=1.5, label=f"{label} (N = {values.size})")
        ax.legend(fontsize=8)
    ax.axvline(0.0, color="0.5", linewidth=0.8)
    ax.set_xlabel("dh [m]")
    ax.set_ylabel("frequency [%]")
    ax.set_title(title)
    fig.tight_layout()
    return _png(fig)


def dh_map(differences, title):
    """PNG of the dh of `differences` (height_differences.Differences): the grid for a DEM, the points
    coloured otherwise; RdBu_r centred on 0, limits +-map_limit."""
    limit = map_limit(differences.dh)
    norm = Normalize(-limit, limit)
    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot()
    if differences.grid is not None:
        x0, dx, _, y0, _, dy = differences.grid.geotransform
        rows, cols = differences.grid.shape
        image = ax.imshow(differences.grid.values, cmap=CMAP, norm=norm, interpolation="nearest",
                          extent=(x0, x0 + cols * dx, y0 + rows * dy, y0))
    else:
        order = np.argsort(np.abs(differences.dh))      # large |dh| drawn last, on top
        image = ax.scatter(differences.x[order], differences.y[order], c=differences.dh[order], cmap=CMAP,
                           norm=norm, s=2, linewidths=0)
        ax.set_aspect("equal")
    ax.set_facecolor("0.15")
    fig.colorbar(image, ax=ax, label="dh [m]", extend="both")
    unit = "deg" if differences.srs.IsGeographic() else "m"
    ax.set_xlabel(f"x [{unit}] ({differences.srs.GetName()})")
    ax.set_ylabel(f"y [{unit}]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_title(title)
    fig.tight_layout()
    return _png(fig)
