"""The co-registration step (pushbroom:coregisterdem): the shift (and optional tilt) of a DEM against a reference
DEM over stable terrain (coregistration.coregister, Nuth and Kääb 2011), the co-registered DEM and a report.

The co-registered DEM is the DEM's heights with the vertical correction added, on its grid moved by the horizontal
shift (its geotransform translated: no height is resampled), in the DEM's own height datum; written window by window
(tasks on the chosen execution), assembled by GDAL as a tiled GeoTIFF with overviews, atomically. The report (HTML)
and the log give the shift, its iterations and the stable cells' dh before and after."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from .. import progress
from ..adjustment.report import Section, render_text, write_html
from ..atomic import work_dir
from ..execution import Execution, run_tasks
from ..progress import Feedback
from ..surface.geotiff import Frame, assemble_tiles, raster_output, write_float_raster
from ..task_runtime import check_cancel
from ..tiling import tile_grid
from .coregistration import WINDOW, CoregParams, CoregResult, Shift, coregister
from .height_differences import Reference
from .rasters import Grid, open_raster, raster_srs, read_grid

#: the statistics rows of the report: (label, Stats attribute)
STAT_ROWS = (("N", "n"), ("median", "median"), ("NMAD", "nmad"), ("mean", "mean"), ("RMS", "rms"))


@dataclass(frozen=True)
class CoregisterDemParams:
    """pushbroom:coregisterdem's settings: the DEM, the reference, the outputs and the CoregParams."""

    dem: str
    reference: str
    output: str  # the co-registered DEM
    report: str | None = None  # HTML report
    coreg: CoregParams = field(default_factory=CoregParams)
    cog: bool = False  # the co-registered DEM as a Cloud-Optimised GeoTIFF


@dataclass(frozen=True)
class CoregisterDemResult:
    result: CoregResult
    output: str
    report: str | None


def write_window(
    dem: str, window: tuple[int, int, int, int], shift: Shift, units: tuple[float, float], path: str
) -> str:
    """One window of the co-registered DEM as a GeoTIFF tile at `path` (a task of run_tasks)."""
    grid = read_grid(open_raster(dem, "DEM"), window=window)
    moved = Grid(grid.values, shift.moved(grid.geotransform, units), grid.srs)
    check_cancel()
    x, y = moved.centres()
    heights = moved.values + shift.vertical(x, y, units)
    return write_float_raster(path, heights, moved.geotransform, moved.srs, overviews=False)


def write_coregistered(
    dem: str,
    shift: Shift,
    units: tuple[float, float],
    output: str,
    execution: Execution,
    feedback: Feedback | None,
    cog: bool = False,
) -> str:
    """The co-registered DEM at `output` (module docstring), a Cloud-Optimised GeoTIFF where `cog`."""
    source = open_raster(dem, "DEM")
    size, srs, gt = (source.RasterXSize, source.RasterYSize), raster_srs(source), source.GetGeoTransform()
    source = None
    with work_dir(output, "the co-registered DEM's tiles") as tiles:
        windows = tile_grid(size, WINDOW)
        tasks = [(dem, w, shift, units, os.path.join(tiles, f"dem-{k:05d}.tif")) for k, w in enumerate(windows)]
        written = run_tasks(write_window, tasks, execution, progress.scaled(feedback, 0, 50), "DEM windows")
        with raster_output(output, cog, progress.scaled(feedback, 80, 100) if cog else None) as tmp:
            assemble_tiles(
                written,
                tmp,
                Frame(shift.moved(gt, units), size, srs),
                description="co-registered DEM (m)",
                metadata={
                    "PUSHBROOM_SHIFT_EAST_M": f"{shift.east:.4f}",
                    "PUSHBROOM_SHIFT_NORTH_M": f"{shift.north:.4f}",
                    "PUSHBROOM_SHIFT_UP_M": f"{shift.up:.4f}",
                    "PUSHBROOM_TILT_EAST": f"{shift.tilt_east:.6e}",
                    "PUSHBROOM_TILT_NORTH": f"{shift.tilt_north:.6e}",
                },
                feedback=progress.scaled(feedback, 50, 80 if cog else 100),
            )
    return output


def sections(result: CoregResult, dem: str, reference: Reference) -> list[Section]:
    """The report's Sections: the shift, the stable cells' dh before and after, the iterations."""
    s, cell, (se, sn, su) = result.shift, result.cell, result.sigma
    shift = Section(
        f"Co-registration of {dem} to {reference.path} (Nuth and Kääb 2011)",
        ("", "value", "standard error", "unit"),
        [
            ("shift east", f"{s.east:+.3f}", f"{se:.3f}", "m"),
            ("shift north", f"{s.north:+.3f}", f"{sn:.3f}", "m"),
            ("shift east", f"{s.east / cell:+.4f}", f"{se / cell:.4f}", "cells"),
            ("shift north", f"{s.north / cell:+.4f}", f"{sn / cell:.4f}", "cells"),
            ("vertical shift (at the DEM's centre)", f"{s.up:+.3f}", f"{su:.3f}", "m"),
            ("tilt east", f"{s.tilt_east:+.3e}", "", "m/m"),
            ("tilt north", f"{s.tilt_north:+.3e}", "", "m/m"),
            ("iterations", str(result.iterations), "", ""),
        ],
        notes=[
            f"The DEM's grid moved by the horizontal shift, its heights corrected by the vertical shift and the tilt "
            f"(a plane about the DEM's centre, {s.centre[0]:.3f}, {s.centre[1]:.3f} in its CRS); cell {cell:.3f} m; "
            f"the reference resampled onto the DEM's cells ({result.resampling}), its {reference.datum} heights in the "
            "DEM's datum (EGM96 where the two differ). The standard errors: the fit's covariance, "
            "the residuals counted once per cell of the coarser DEM; zero where the horizontal shift was not fitted."
        ],
    )
    rows = [
        (
            label,
            *(f"{getattr(stats, key):.3f}" if key != "n" else str(stats.n) for stats in (result.before, result.after)),
        )
        for label, key in STAT_ROWS
    ]
    stable = Section(
        "dh = DEM - reference on the stable cells (m)",
        ("", "before", "after co-registration"),
        rows,
        notes=[
            "Stable cells: both heights, the reference's slope at most the largest slope, outside the unstable mask."
        ],
    )
    history = Section(
        "Iterations",
        ("iteration", "east (m)", "north (m)", "up (m)"),
        [(str(k + 1), f"{h.east:+.3f}", f"{h.north:+.3f}", f"{h.up:+.3f}") for k, h in enumerate(result.history)],
    )
    return [shift, stable, history]


def coregister_dem(params: CoregisterDemParams, feedback: Feedback | None = None) -> CoregisterDemResult:
    """Co-register the DEM of `params` to its reference and write the co-registered DEM and the report. Raises
    InputError, coregistration.CoregistrationError (nothing written), CancelledError."""
    coreg = params.coreg.check()
    reference = Reference(params.reference, coreg.reference_heights, coreg.reference_nodata)
    result = coregister(params.dem, reference, coreg, progress.scaled(feedback, 0, 80))
    parts = sections(result, params.dem, reference)
    progress.ensure(feedback).pushInfo(render_text(parts))
    output = write_coregistered(
        params.dem,
        result.shift,
        result.units,
        params.output,
        coreg.execution,
        progress.scaled(feedback, 80, 98),
        params.cog,
    )
    report = write_html(params.report, "Co-registration", parts=parts) if params.report else None
    progress.step(feedback, 100)
    return CoregisterDemResult(result, output, report)
