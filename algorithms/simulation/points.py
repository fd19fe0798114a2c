"""Control/check point candidates: open, flat ground points seen by every image, with their true
image coordinates (from the continuous truth) and simulated measurements (Gaussian noise of
`sigma` px, optional blunders of 5-20 px in a random direction, flagged)."""

import math
from dataclasses import dataclass

import numpy as np

from ..dem import dem_window
from ..geodesy import geodetic_to_ecef
from .terrain import BARE, CROPS
from .tiles import TILE, cut, grid_array, grown, release, windows

EDGE_PX = 10.0  # candidates keep this distance from every image border
VISIBLE_M = 0.5  # a candidate is visible if the ray of its true pixel lands this close
SLOPE_MAX = 0.15  # rise per metre (8.5 deg) allowed across a candidate's neighbourhood


@dataclass
class Candidates:
    """Point candidates and their coordinates in every image (dicts keyed by image name)."""

    lon: np.ndarray
    lat: np.ndarray
    h: np.ndarray
    true: dict  # name -> (n, 2) col, row
    measured: dict  # name -> (n, 2)
    blunder: dict  # name -> (n,) bool

    def __len__(self):
        return len(self.lon)


def select_sites(terrain, images, count, clearance_m, rng, tries=20, folder=None, tile=TILE):
    """Up to `count` sites (lon, lat) on eligible cells (`eligible_cells`, a grid array in `folder`
    or in memory) inside every image (EDGE_PX), spread out: first one site in each stratum of a
    ceil(sqrt(count))^2 division of the grid (strata in random order), then anywhere, always at
    least half a stratum from the sites already chosen; `tries` random cells per attempt, drawn
    by rank among the eligible cells (EligibleCells: no index array of the grid's cells)."""
    grid = terrain.grid
    eligible = eligible_cells(terrain, clearance_m, folder, tile)
    k = max(1, int(math.ceil(math.sqrt(count))))
    spacing = site_spacing(grid, count)
    sites = []

    def take(cells):
        for rank in rng.choice(cells.size, size=min(tries, cells.size), replace=False):
            i, j = cells.cell(int(rank))
            if any(math.hypot(i - a, j - b) < spacing for a, b in sites):
                continue
            xyz = geodetic_to_ecef(*grid.lonlat(j, i), float(terrain.dtm[i, j]))
            if all(_inside(image, xyz) for image in images):
                sites.append((i, j))
                return

    for stratum in rng.permutation(k * k):
        si, sj = divmod(int(stratum), k)
        if len(sites) < count:
            cells = EligibleCells(
                eligible,
                (si * grid.rows // k, (si + 1) * grid.rows // k, sj * grid.cols // k, (sj + 1) * grid.cols // k),
            )
            if cells.size:
                take(cells)
    if len(sites) < count:
        cells = EligibleCells(eligible, (0, grid.rows, 0, grid.cols))
        for _ in range(count - len(sites)):
            if cells.size:
                take(cells)
    release(eligible)
    if not sites:
        return np.zeros((0, 2))
    i, j = np.array(sites).T
    return np.column_stack(grid.lonlat(j, i))


def site_spacing(grid, count):
    """The least distance (cells) between the sites select_sites chooses for `count` sites on `grid`: half a
    stratum of its ceil(sqrt(count))^2 division."""
    return 0.5 * min(grid.rows, grid.cols) / max(1, int(math.ceil(math.sqrt(count))))


def shortfall(asked, sites, candidates, blunders, spacing_m, clearance_m):
    """A warning where fewer candidates or blunders were made than asked (None where all were): `asked`
    candidates, `sites` chosen (select_sites, `spacing_m` apart on open ground `clearance_m` around),
    `candidates` (Candidates: the sites seen by every image), `blunders` asked."""
    lines = []
    n = len(candidates)
    if n < asked:
        hidden = (
            f", and {sites - n} of them {'is' if sites - n == 1 else 'are'} hidden from an image by trees or buildings"
            if sites > n
            else ""
        )
        lines.append(
            f"{n} control/check point candidates made of the {asked} asked: the scene holds {sites} sites "
            f"of open, flat ground (bare soil or crops {clearance_m:.0f} m around, inside every image) at "
            f"least {spacing_m:.0f} m apart{hidden}; a larger scene (SIZE_KM) holds more"
        )
    measurements = n * len(candidates.measured)
    made = int(sum(int(b.sum()) for b in candidates.blunder.values()))
    if made < blunders:
        lines.append(
            f"{made} blunders made of the {blunders} asked: the {n} candidates have {measurements} image "
            "measurements, and a measurement takes one blunder at most"
        )
    return "; ".join(lines) or None


class EligibleCells:
    """The True cells of a bool grid array within `window` (i0, i1, j0, j1), in row-major order (as
    numpy.nonzero lists them), addressed by rank: only the count per row is held."""

    BAND = 256

    def __init__(self, mask, window):
        self.mask, self.window = mask, window
        i0, i1, j0, j1 = window
        counts = [
            np.count_nonzero(cut(mask, (a, min(a + self.BAND, i1), j0, j1)), axis=1) for a in range(i0, i1, self.BAND)
        ]
        self.ends = np.cumsum(np.concatenate(counts)) if counts else np.zeros(0, np.int64)
        self.size = int(self.ends[-1]) if self.ends.size else 0

    def cell(self, rank):
        """(row, column) in the grid of the cell of rank `rank`."""
        i0, _, j0, j1 = self.window
        r = int(np.searchsorted(self.ends, rank, side="right"))
        before = int(self.ends[r - 1]) if r else 0
        j = np.flatnonzero(cut(self.mask, (i0 + r, i0 + r + 1, j0, j1))[0])[rank - before]
        return i0 + r, j0 + int(j)


def eligible_cells(terrain, clearance_m, folder=None, tile=TILE):
    """Cells whose whole +-clearance_m neighbourhood is BARE or CROPS and whose DTM there stays
    within +-SLOPE_MAX x clearance of its middle (open, flat ground: no occlusion, symmetric
    markers): a bool grid array, made tile by tile with the neighbourhood as margin."""
    from scipy import ndimage

    grid = terrain.grid
    de, dn = grid.cell_metres
    ri, rj = int(math.ceil(clearance_m / dn)), int(math.ceil(clearance_m / de))
    size = (2 * ri + 1, 2 * rj + 1)
    out = grid_array(folder, "eligible", grid.shape, np.bool_)
    for window in windows(grid.shape, tile):
        outer, inner = grown(window, grid.shape, ri, ri, rj, rj)
        dtm = cut(terrain.dtm, outer)
        open_ground = np.isin(cut(terrain.classes, outer), (BARE, CROPS)).astype(np.uint8)
        relief = ndimage.maximum_filter(dtm, size) - ndimage.minimum_filter(dtm, size)
        ok = (ndimage.minimum_filter(open_ground, size) > 0) & (relief <= 2.0 * SLOPE_MAX * clearance_m)
        i0, i1, j0, j1 = window
        out[i0:i1, j0:j1] = ok[inner]
    return out


def ground_heights(array, grid, lon, lat):
    """dem.Dem.height of the grid array `array` at each (lon, lat), read from the few cells around the
    point (dem.dem_window)."""
    return np.array(
        [
            dem_window(array, grid.geotransform, (np.nan, np.nan), (x, y, x, y)).height(x, y)
            for x, y in zip(np.atleast_1d(lon), np.atleast_1d(lat))
        ]
    )


def _inside(image, xyz):
    col, row = image.ground_to_image(xyz)
    return EDGE_PX <= col[0] <= image.ncols - EDGE_PX and EDGE_PX <= row[0] <= image.nrows - EDGE_PX


def level_pads(terrain, lon, lat, radius_m):
    """Level the ground under each site: within `radius_m` the DTM and DSM become the plane
    fitted to the DTM there, blended back to the terrain linearly out to 1.5 radius (markers are
    laid on levelled pads, so the marker's image is symmetric)."""
    grid = terrain.grid
    de, dn = grid.cell_metres
    outer = 1.5 * radius_m
    ri, rj = int(math.ceil(outer / dn)) + 1, int(math.ceil(outer / de)) + 1
    x, y = grid.vertex(lon, lat)
    for xc, yc in zip(np.atleast_1d(x), np.atleast_1d(y)):
        i0, j0 = int(round(yc)) - ri, int(round(xc)) - rj
        ii, jj = np.mgrid[i0 : i0 + 2 * ri + 1, j0 : j0 + 2 * rj + 1]
        e, n = (jj - xc) * de, (yc - ii) * dn
        d = np.hypot(e, n)
        inner = d <= radius_m
        design = np.column_stack([np.ones(inner.sum()), e[inner], n[inner]])
        coef = np.linalg.lstsq(design, terrain.dtm[ii[inner], jj[inner]], rcond=None)[0]
        plane = coef[0] + coef[1] * e + coef[2] * n
        weight = np.clip((outer - d) / (outer - radius_m), 0.0, 1.0)
        for z in (terrain.dtm, terrain.dsm):
            z[ii, jj] = weight * plane + (1.0 - weight) * z[ii, jj]


def image_coordinates(sites_lonlat, heights, images, surface, sigma, blunders, rng):
    """Candidates at (lon, lat, h): true image coordinates in every image (continuous truth),
    dropping points occluded in any image; measurements = truth + N(0, sigma) and `blunders`
    gross errors spread over random (point, image) pairs."""
    lon, lat = sites_lonlat[:, 0], sites_lonlat[:, 1]
    xyz = geodetic_to_ecef(lon, lat, heights)
    true, keep = {}, np.ones(len(lon), bool)
    for image in images:
        col, row = image.ground_to_image(xyz)
        pos, mat = image.line_geometry(row)
        ground = surface.trace(pos, mat, image.look_vectors(col))
        seen = geodetic_to_ecef(ground[:, 0], ground[:, 1], ground[:, 2])
        keep &= np.linalg.norm(seen - xyz, axis=1) < VISIBLE_M
        true[image.name] = np.column_stack([col, row])
    true = {name: v[keep] for name, v in true.items()}
    n = int(keep.sum())
    measured = {name: v + rng.normal(0.0, sigma, v.shape) for name, v in true.items()}
    blunder = {name: np.zeros(n, bool) for name in true}
    names = list(true)
    pairs = rng.permutation(n * len(names))[: min(blunders, n * len(names))]
    for flat in pairs:
        name, k = names[flat % len(names)], flat // len(names)
        angle = rng.uniform(0, 2 * math.pi)
        measured[name][k] += rng.uniform(5.0, 20.0) * np.array([math.cos(angle), math.sin(angle)])
        blunder[name][k] = True
    return Candidates(lon[keep], lat[keep], heights[keep], true, measured, blunder)
