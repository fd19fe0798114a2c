"""The accuracy assessment: dh of a point cloud and/or a DEM against a reference (height_differences),
each value labelled with its class (a class raster or polygons, classes.py) and its slope class
(flat/moderate vs mountainous, Kornus et al. 2006, section 3.7), summed up for the tables and figures of
report.py.

`assess` holds every difference of each input (Assessed: the values themselves, for the library and the
tests). The step uses `assess_by_parts`: the point cloud in chunks of CHUNK points and the DEM in windows
of TILE x TILE cells, each part's Assessed added into a Summary (mergeable statistics per point group,
class and terrain, statistics.DhSummary; a map of at most MAP_CELLS cells a side of the DEM's dh, or of
at most MAP_POINTS points thinned evenly from the cloud) and dropped, so that memory follows the part,
not the data. The DEM's dh windows are written as GeoTIFF tiles where a folder is given. The statistics
of the parts are those of the whole: the reference, its slope and the classes of a part are the whole
data's there (height_differences)."""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from .. import progress
from ..errors import InputError
from ..progress import Feedback
from ..surface.geotiff import write_float_raster
from ..surface.point_input import point_chunks, point_count
from ..tiling import tile_grid
from .classes import slope_classes
from .height_differences import Differences, Reference, ReferenceReach, dem_differences, point_differences
from .rasters import Grid, open_raster, raster_srs
from .statistics import DhSummary, labelled, merge_labelled

SLOPE_THRESHOLD = 10.0  # degrees
#: points per chunk and DEM cells per window side of assess_by_parts
CHUNK = 1_000_000
TILE = 1024
#: the dh map figure: at most MAP_CELLS cells a side of a DEM, at most MAP_POINTS points
MAP_CELLS = 1000
MAP_POINTS = 200_000


class Labelling(NamedTuple):
    """How each dh is labelled: its class from `classes` (a classes.ClassRaster or classes.PolygonClasses;
    None: no classes) and its terrain by the reference's slope, mountainous above `slope_threshold`
    (degrees)."""

    classes: Any = None
    slope_threshold: float = SLOPE_THRESHOLD


@dataclass
class Assessed:
    differences: Differences
    classes: np.ndarray = None  # (n,) class of each dh (classes.NO_CLASS: none)
    class_names: dict = None
    terrain: np.ndarray = None  # (n,) classes.FLAT / MOUNTAINOUS
    terrain_names: dict = None


@dataclass
class Summary:
    """The statistics of one assessed input, added up over its parts (`add`): DhSummary of all its dh and
    {label: DhSummary} per point group, class and terrain (None where the input has no such label), the
    left-out counts, and the dh map: `map_grid` (a DEM's dh on every `map_step`-th cell of each row and
    column: the centre cell of each block of map_step x map_step cells) or `map_points` (x, y, dh of every
    `map_step`-th point)."""

    what: str
    source: str
    srs: object
    all: DhSummary = field(default_factory=DhSummary)
    groups: dict = None
    classes: dict = None
    class_names: dict = None
    terrain: dict = field(default_factory=dict)
    terrain_names: dict = None
    excluded: dict = field(default_factory=dict)
    map_grid: Grid = None
    map_points: tuple = None
    map_step: int = 1
    seen: int = 0  # points with a dh so far (the thinning's position)
    tiles: list = None  # a DEM's dh tiles written by assess_by_parts
    size: tuple = None  # a DEM's (cols, rows)
    geotransform: tuple = None  # and geotransform

    def add(self, assessed):
        """Add the part `assessed` (an Assessed); returns self."""
        d = assessed.differences
        self.all = self.all.merge(DhSummary.of(d.dh))
        if d.group is not None:
            self.groups = merge_labelled(self.groups or {}, labelled(d.dh, d.group))
        if assessed.classes is not None:
            self.classes = merge_labelled(self.classes or {}, labelled(d.dh, assessed.classes))
            self.class_names = assessed.class_names
        self.terrain = merge_labelled(self.terrain, labelled(d.dh, assessed.terrain))
        self.terrain_names = assessed.terrain_names
        for reason, n in d.excluded.items():
            self.excluded[reason] = self.excluded.get(reason, 0) + n
        if d.grid is not None:
            self._map_cells(d.grid)
        else:
            self._map_points(d)
        return self

    def _map_cells(self, tile):
        """Put the cells of the dh window `tile` that fall on the map's lattice into the map."""
        x0, dx, _, y0, _, dy = self.map_grid.geotransform
        step = self.map_step
        c0 = int(round((tile.geotransform[0] - x0) / (dx / step)))
        r0 = int(round((tile.geotransform[3] - y0) / (dy / step)))
        centre = step // 2  # each map cell shows the centre cell of its block
        first_r, first_c = (centre - r0) % step, (centre - c0) % step
        part = tile.values[first_r::step, first_c::step]
        i, j = (r0 + first_r) // step, (c0 + first_c) // step
        self.map_grid.values[i : i + part.shape[0], j : j + part.shape[1]] = part

    def _map_points(self, d):
        """Keep every map_step-th point of the stream; past MAP_POINTS, every other one of those kept."""
        k = np.arange(self.seen, self.seen + len(d.dh))
        keep = k % self.map_step == 0
        self.seen += len(d.dh)
        old = self.map_points or (np.zeros(0), np.zeros(0), np.zeros(0))
        self.map_points = tuple(np.concatenate([a, b[keep]]) for a, b in zip(old, (d.x, d.y, d.dh)))
        while len(self.map_points[0]) > MAP_POINTS:
            self.map_points = tuple(a[::2] for a in self.map_points)
            self.map_step *= 2


def summarized(assessed):
    """The Summary of one whole Assessed."""
    d = assessed.differences
    summary = Summary(d.what, d.source, d.srs)
    if d.grid is not None:
        summary.map_grid, summary.map_step = _map_grid(d.grid.shape, d.grid.geotransform, d.srs)
    return summary.add(assessed)


def _map_grid(shape, geotransform, srs):
    """(an empty dh map Grid of at most MAP_CELLS a side for a grid of `shape`, its step in cells)."""
    step = max(1, math.ceil(max(shape) / MAP_CELLS))
    x0, dx, _, y0, _, dy = geotransform
    values = np.full((math.ceil(shape[0] / step), math.ceil(shape[1] / step)), np.nan)
    return Grid(values, (x0, dx * step, 0.0, y0, 0.0, dy * step), srs), step


def labels(source, differences):
    """Class of each dh of `differences` from a ClassRaster or PolygonClasses."""
    if differences.grid is not None:
        return source.on_grid(differences.grid)[differences.valid]
    return source.at_points(differences.x, differences.y, differences.srs)


def _assessed(d: Differences, labelling: Labelling) -> Assessed:
    """The Assessed of the Differences `d`: terrain classes by slope, classes from `classes` where given
    (`labelling`)."""
    classes, slope_threshold = labelling
    terrain, terrain_names = slope_classes(d.slope, slope_threshold)
    assessed = Assessed(d, terrain=terrain, terrain_names=terrain_names)
    if classes is not None:
        assessed.classes, assessed.class_names = labels(classes, d), classes.names
    return assessed


def _check(points: Any, dem: Any, slope_threshold: float) -> None:
    if points is None and dem is None:
        raise InputError("give a point cloud, a DEM or both to assess")
    if not slope_threshold > 0:
        raise InputError(f"the slope threshold must be a positive angle in degrees, not {slope_threshold}")


def assess(
    reference: Reference,
    points: str | os.PathLike[str] | None = None,
    dem: str | os.PathLike[str] | None = None,
    points_datum: str = "ellipsoidal",
    dem_datum: str = "ellipsoidal",
    labelling: Labelling = Labelling(),
    feedback: Feedback | None = None,
) -> list[Assessed]:
    """[Assessed] of the point cloud `points` and the DEM raster `dem` (either or both) against the
    Reference `reference` (its raster, datum and declared void value), every difference held, each
    labelled as `labelling` says. Implausible reference heights are reported as a warning
    (height_differences)."""
    _check(points, dem, labelling.slope_threshold)
    jobs: list[tuple[Callable[..., Differences], str | os.PathLike[str] | None, str]] = [
        (point_differences, points, points_datum),
        (dem_differences, dem, dem_datum),
    ]
    jobs = [job for job in jobs if job[1] is not None]
    out = []
    for k, (compute, path, datum) in enumerate(jobs):
        span = 100.0 / len(jobs)
        d = compute(path, reference, datum, progress.scaled(feedback, k * span, (k + 0.8) * span))
        if not d.dh.size:
            raise InputError(f"no {d.what} of {path} has a reference height: check that the reference covers it")
        out.append(_assessed(d, labelling))
        progress.step(feedback, (k + 1) * span, f"{d.what}: {d.dh.size} height differences")
    return out


def assess_by_parts(
    reference: Reference,
    points: str | os.PathLike[str] | None = None,
    dem: str | os.PathLike[str] | None = None,
    points_datum: str = "ellipsoidal",
    dem_datum: str = "ellipsoidal",
    labelling: Labelling = Labelling(),
    feedback: Feedback | None = None,
    tiles: str | None = None,
) -> list[Summary]:
    """[Summary] of the point cloud `points` and the DEM raster `dem` (either or both) against the
    Reference `reference` (as assess), read in parts (module docstring). `tiles`: a folder where the DEM's dh
    windows are written as GeoTIFF tiles (listed in the Summary's `tiles`), or None."""
    _check(points, dem, labelling.slope_threshold)
    span = 100.0 / ((points is not None) + (dem is not None))
    out = []
    if points is not None:
        out.append(_points_by_chunks(reference, points, points_datum, labelling, progress.scaled(feedback, 0, span)))
    if dem is not None:
        out.append(
            _dem_by_windows(reference, dem, dem_datum, labelling, progress.scaled(feedback, 100 - span, 100), tiles)
        )
    return out


def _points_by_chunks(
    reference: Reference,
    path: str | os.PathLike[str],
    datum: str,
    labelling: Labelling,
    feedback: Feedback | None,
) -> Summary:
    """The Summary of the point cloud at `path` (heights in `datum`), read in chunks of CHUNK points."""
    reach, summary, total = ReferenceReach(reference.path, reference.nodata), None, max(point_count(path), 1)
    for k, chunk in enumerate(point_chunks(path, None, CHUNK)):
        progress.step(feedback, 100.0 * min(k * CHUNK, total) / total)
        if not len(chunk):
            raise InputError(f"the point cloud {path} holds no point")
        d = point_differences(path, reference, datum, points=chunk, reach=reach, required=False)
        summary = summary or Summary(d.what, str(path), d.srs)
        summary.add(_assessed(d, labelling))
        progress.ensure(feedback).pushInfo(
            f"object points: chunk {k + 1}, {summary.all.n} with a reference height so far"
        )
    progress.warn(feedback, reach.warning())
    if not summary.all.n:
        raise reach.no_heights("the assessed points")
    return summary


def _dem_by_windows(
    reference: Reference,
    path: str | os.PathLike[str],
    datum: str,
    labelling: Labelling,
    feedback: Feedback | None,
    folder: str | None,
) -> Summary:
    """The Summary of the DEM raster at `path` (heights in `datum`), read in windows of TILE x TILE cells;
    the dh windows written as GeoTIFF tiles in `folder` where given."""
    ds = open_raster(path, "DEM")
    size, geotransform, srs = (ds.RasterXSize, ds.RasterYSize), ds.GetGeoTransform(), raster_srs(ds)
    ds = None
    summary = Summary("DEM cells", str(path), srs)
    summary.map_grid, summary.map_step = _map_grid((size[1], size[0]), geotransform, srs)
    summary.tiles = []
    reach, boxes = ReferenceReach(reference.path, reference.nodata), tile_grid(size, TILE)
    for k, box in enumerate(boxes):
        progress.step(feedback, 100.0 * k / len(boxes))
        d = dem_differences(path, reference, datum, window=box, reach=reach)
        summary.add(_assessed(d, labelling))
        if folder is not None:
            summary.tiles.append(
                write_float_raster(
                    os.path.join(folder, f"dh-{k:05d}.tif"), d.grid.values, d.grid.geotransform, srs, overviews=False
                )
            )
    progress.warn(feedback, reach.warning())
    if summary.excluded.get("DEM nodata", 0) == size[0] * size[1]:
        raise InputError(f"the DEM {path} holds no valid height (all cells are nodata)")
    if not summary.all.n:
        raise InputError(
            f"the reference DEM {reference.path} does not overlap the DEM {path} (or holds only nodata "
            "there): choose a reference that covers it"
        )
    summary.size, summary.geotransform = size, geotransform
    return summary
