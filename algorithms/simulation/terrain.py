"""The simulated ground: a real DEM resampled to the scene grid with optional fractal detail (the
DTM), land cover, and surface objects (forest canopy, buildings) that make the DSM.

Source DEM: matplotlib's sample `jacksboro_fault_dem.npz`, a USGS 3 arc-second DEM (344 x 403
cells, 236-1076 m) of the Cumberland Mountains at the Tennessee/Kentucky border. Its stored
`ymin` (36.7329) and `ymax` (36.4462) are swapped, and row 0 is the NORTH edge: read north-up, the
straight Jacksboro fault trends N25W and ends in the south-east at the dendritic arms of Norris
Lake (a flat 305 m = 1000 ft water surface, the tile's lowest area), while Pine Mountain's
escarpment trends N50E, as USGS maps show; read south-up both trends would be mirrored (N25E,
N50W) and the reservoir would lie in the north. `xmin`/`xmax` and the swapped y values are cell
edges (403 x 3" = xmax - xmin). Heights are orthometric (NGVD29, within a metre of EGM96); they
become ellipsoidal by adding the EGM96 geoid undulation from PROJ (about -31 m here).

Beyond the source, for scenes wider than it (a full 60 km SPOT scene), `extended_dem` continues it
honestly and visibly: the source is mirrored across each of its edges into a 3 x 3 block (heights
continuous at the mirror lines, slopes reversed there, so each mirror line is a crease), and the
copies are told apart by a low-frequency fBm relief (wavelengths 6 km down to 750 m, up to 60 m)
that rises from zero at the source's edge to full strength 3 km beyond it. The geoid is PROJ's EGM96
everywhere (not mirrored); the mirrored lake zone holds water only where the continued heights stay
at the lake level. Inside the source nothing changes. The fine fractal detail, land cover, towns and
objects are procedural in the scene's own coordinates, so they never repeat.

Land-cover classes (codes in the class raster): see CLASSES. Surface objects sit only on their
classes: forest canopy (class FOREST) and buildings (class CITY); elsewhere DSM = DTM.

Every grid is built tile by tile (tiles.py), with the margins each kernel's neighbourhood needs, so
the result does not depend on the tiling: in files of a work folder (simulate_scene), or in memory
where no folder is given (tests)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..crs import egm96_undulation
from ..dem import grid_bounds
from ..errors import InputError
from ..geodesy import metres_per_degree
from .grid import Grid
from .noise import fbm, gradient_noise, hash3, uniform, worley
from .render import bilinear
from .tiles import TILE, cut, grid_array, grown, release, windows

WATER, BARE, CROPS, FOREST, CITY = 1, 2, 3, 4, 5
CLASSES = {
    0: "nodata",
    WATER: "water",
    BARE: "bare fields",
    CROPS: "grass/crops",
    FOREST: "forest",
    CITY: "city/buildings",
}
LAKE_LEVEL = 305.0  # Norris Lake water surface in the source DEM, m (orthometric)
LAKE_MIN_CELLS = 200  # source-DEM components at or below LAKE_LEVEL that count as the lake
FRACTAL_AMPLITUDE = 4.0  # m, largest fractal octave at fractal = 1
FRACTAL_WAVELENGTH = 180.0  # m: the source DEM resolves ~2 x 90 m; detail is added below that
FRACTAL_PERSISTENCE = 2.0**-0.8  # amplitude ratio per octave (fBm with Hurst exponent 0.8)
CONTINUATION_AMPLITUDE = 60.0  # m, relief that tells the mirrored copies of the source apart
CONTINUATION_WAVELENGTH = 6000.0  # m, its largest octave (4 octaves)
CONTINUATION_RAMP = 3000.0  # m beyond the source's edge to its full strength
CONTINUATION_SEED = 977  # fixed: the extended source is the same for every scene seed
CITY_REACH_M = 60.0  # a city cell reads the DTM at its lot's centre, at most this far


@dataclass
class SourceDem:
    """The source DEM on its own north-up grid: orthometric heights, geoid undulation, lake mask."""

    heights: np.ndarray  # (rows, cols) float64, m above the geoid
    geoid: np.ndarray  # (rows, cols) float64, EGM96 undulation N, m
    lake: np.ndarray  # (rows, cols) bool, Norris Lake zone
    geotransform: tuple
    planning_range: tuple = None  # (low, high) ellipsoidal heights the acquisition is planned for

    def __post_init__(self):
        if self.planning_range is None:
            ellipsoidal = self.heights + self.geoid
            self.planning_range = (float(ellipsoidal.min()), float(ellipsoidal.max()))

    @property
    def bounds(self):
        return grid_bounds(self.geotransform, self.heights.shape)

    @property
    def centre(self):
        lon_min, lat_min, lon_max, lat_max = self.bounds
        return 0.5 * (lon_min + lon_max), 0.5 * (lat_min + lat_max)


def jacksboro_dem():
    """The Jacksboro sample DEM, north-up (see the module docstring for the orientation check)."""
    from matplotlib import cbook
    from scipy import ndimage

    data = np.load(cbook.get_sample_data("jacksboro_fault_dem.npz", asfileobj=False))
    heights = data["elevation"].astype(np.float64)
    lat_north = float(max(data["ymin"], data["ymax"]))
    geotransform = (float(data["xmin"]), float(data["dx"]), 0.0, lat_north, 0.0, -float(data["dy"]))
    labels, count = ndimage.label(heights <= LAKE_LEVEL)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    lake = (sizes >= LAKE_MIN_CELLS)[labels] & (labels > 0)
    lake = ndimage.binary_dilation(lake, iterations=1)
    return SourceDem(heights, _geoid_undulation(heights.shape, geotransform), lake, geotransform)


def extended_dem(source):
    """The source mirrored into a 3 x 3 block with a low-frequency continuation relief outside it
    (module docstring); the source's own cells keep their heights. Its planning range stays the
    source's: the continuation moves heights by at most CONTINUATION_AMPLITUDE (60 m), which shifts
    a footprint by 60 m x tan 27 deg = 31 m at SPOT's widest view, well inside the ground margin
    the scene adds (scene.TERRAIN_MARGIN_M)."""
    rows, cols = source.heights.shape
    pad = ((rows, rows), (cols, cols))
    lon0, dlon, _, lat0, _, dlat = source.geotransform
    geotransform = (lon0 - cols * dlon, dlon, 0.0, lat0 - rows * dlat, 0.0, dlat)
    me, mn = metres_per_degree(source.centre[1])
    de, dn = dlon * me, -dlat * mn
    heights = np.pad(source.heights, pad, mode="symmetric")
    _add_continuation(heights, rows, cols, de, dn)
    lake = np.pad(source.lake, pad, mode="symmetric")
    return SourceDem(heights, _geoid_undulation(heights.shape, geotransform), lake, geotransform, source.planning_range)


@njit(cache=True, nogil=True, parallel=True)
def _add_continuation(heights, rows, cols, de, dn):
    """heights += w(d) A fbm((e, n) / L) outside the middle block of `rows` x `cols` cells, d the
    distance beyond its edge, w rising linearly from 0 to 1 over CONTINUATION_RAMP."""
    for i in prange(heights.shape[0]):
        dy = max(rows - i - 0.5, i + 0.5 - 2 * rows, 0.0) * dn
        for j in range(heights.shape[1]):
            dx = max(cols - j - 0.5, j + 0.5 - 2 * cols, 0.0) * de
            w = min(math.hypot(dx, dy) / CONTINUATION_RAMP, 1.0)
            if w > 0.0:
                heights[i, j] += (
                    w
                    * CONTINUATION_AMPLITUDE
                    * fbm(
                        j * de / CONTINUATION_WAVELENGTH, -i * dn / CONTINUATION_WAVELENGTH, CONTINUATION_SEED, 4, 0.5
                    )
                )


def _geoid_undulation(shape, geotransform):
    """EGM96 undulation N at the cell centres (crs.egm96_undulation)."""
    rows, cols = shape
    lon0, dlon, _, lat0, _, dlat = geotransform
    lon, lat = np.meshgrid(lon0 + (np.arange(cols) + 0.5) * dlon, lat0 + (np.arange(rows) + 0.5) * dlat)
    return egm96_undulation(lon, lat)


@njit(cache=True, nogil=True)
def _keys(t):
    """Keys' cubic convolution kernel (a = -0.5)."""
    t = abs(t)
    if t < 1.0:
        return (1.5 * t - 2.5) * t * t + 1.0
    if t < 2.0:
        return ((-0.5 * t + 2.5) * t - 4.0) * t + 2.0
    return 0.0


@njit(cache=True, nogil=True, parallel=True)
def cubic_resample(src, x0, dx, y0, dy, rows, cols):
    """out[i, j] = sum_{m,n} src[.] keys(x - n) keys(y - m) at source vertex coordinates
    x = x0 + j dx, y = y0 + i dy (edge cells repeated)."""
    out = np.empty((rows, cols))
    sr, sc = src.shape
    for i in prange(rows):
        y = y0 + i * dy
        iy = int(math.floor(y))
        for j in range(cols):
            x = x0 + j * dx
            ix = int(math.floor(x))
            acc = 0.0
            for m in range(iy - 1, iy + 3):
                wy = _keys(y - m)
                mm = min(max(m, 0), sr - 1)
                for n in range(ix - 1, ix + 3):
                    acc += wy * _keys(x - n) * src[mm, min(max(n, 0), sc - 1)]
            out[i, j] = acc
    return out


@njit(cache=True, nogil=True, parallel=True)
def _add_fractal(dtm, e0, de, n0, dn, wavelength, octaves, amplitude, persistence, seed):
    """dtm += amplitude * sum_k persistence^k noise(2^k (e, n) / wavelength)."""
    rows, cols = dtm.shape
    for i in prange(rows):
        n = n0 - i * dn
        for j in range(cols):
            e = e0 + j * de
            acc = 0.0
            amp = amplitude
            f = 1.0 / wavelength
            for k in range(octaves):
                acc += amp * gradient_noise(e * f, n * f, seed + 101 * k)
                amp *= persistence
                f *= 2.0
            dtm[i, j] += acc


@njit(cache=True, nogil=True)
def gradient_en(z, i, j, de, dn):
    """(dz/dE, dz/dN) at cell (i, j) of a north-up grid (rows run south) with cells de x dn metres:
    central differences, one-sided at the edges."""
    rows, cols = z.shape
    i0, i1 = max(i - 1, 0), min(i + 1, rows - 1)
    j0, j1 = max(j - 1, 0), min(j + 1, cols - 1)
    return (z[i, j1] - z[i, j0]) / ((j1 - j0) * de), (z[i0, j] - z[i1, j]) / ((i1 - i0) * dn)


@njit(cache=True, nogil=True, parallel=True)
def slope_degrees(z, de, dn):
    """Terrain slope atan(|grad z|), degrees."""
    rows, cols = z.shape
    out = np.empty((rows, cols), np.float32)
    for i in prange(rows):
        for j in range(cols):
            gx, gy = gradient_en(z, i, j, de, dn)
            out[i, j] = math.degrees(math.atan(math.sqrt(gx * gx + gy * gy)))
    return out


@njit(cache=True, nogil=True)
def _bilinear_clamped(z, x, y):
    """render.bilinear at (x, y) clamped into the grid."""
    rows, cols = z.shape
    return bilinear(z, min(max(x, 0.0), cols - 1.0), min(max(y, 0.0), rows - 1.0))


@njit(cache=True, nogil=True)
def _city_cell(dtm, e, n, e0, de, n0, dn, town, seed):
    """(object height, feature) of a city cell. Streets of width 14 m on a rotated block grid;
    each block holds 2 x 2 lots, 85 % of them built with a flat-roofed building inset 3-9 m,
    roof at DTM(lot centre) + height, 4-12 m high at the edge, up to 35 m near the centre.
    Feature: 0 street, 1 open lot, >= 2 building id."""
    te, tn, radius, angle, block = town[0], town[1], town[2], town[3], town[4]
    ca, sa = math.cos(angle), math.sin(angle)
    u = ca * (e - te) + sa * (n - tn)
    v = -sa * (e - te) + ca * (n - tn)
    street = 14.0
    bu = math.floor(u / block)
    bv = math.floor(v / block)
    fu = u - bu * block
    fv = v - bv * block
    if fu < street or fv < street:
        return 0.0, 0
    lot = 0.5 * (block - street)
    lu = int((fu - street) // lot)
    lv = int((fv - street) // lot)
    iu = int(bu) * 2 + lu
    iv = int(bv) * 2 + lv
    if uniform(iu, iv, seed) < 0.15:
        return 0.0, 1
    au = street + lu * lot
    av = street + lv * lot
    m1 = 3.0 + 6.0 * uniform(iu, iv, seed + 1)
    m2 = 3.0 + 6.0 * uniform(iu, iv, seed + 2)
    m3 = 3.0 + 6.0 * uniform(iu, iv, seed + 3)
    m4 = 3.0 + 6.0 * uniform(iu, iv, seed + 4)
    if fu < au + m1 or fu > au + lot - m2 or fv < av + m3 or fv > av + lot - m4:
        return 0.0, 1
    cu = bu * block + au + 0.5 * lot
    cv = bv * block + av + 0.5 * lot
    centrality = max(0.0, 1.0 - math.hypot(cu, cv) / radius)
    height = 4.0 + 8.0 * uniform(iu, iv, seed + 5) + 23.0 * centrality * centrality * uniform(iu, iv, seed + 6)
    ce = te + ca * cu - sa * cv
    cn = tn + sa * cu + ca * cv
    base = _bilinear_clamped(dtm, (ce - e0) / de, (n0 - cn) / dn)
    here = _bilinear_clamped(dtm, (e - e0) / de, (n0 - n) / dn)
    return max(base + height - here, 0.5), 2 + (hash3(iu, iv, seed) >> 2)


@njit(cache=True, nogil=True)
def _canopy(e, n, seed):
    """(canopy height, tree id) of a forest cell: crowns on a jittered 8 m lattice, ellipsoidal
    crown tops of radius 0.55-0.7 spacing, stand height 20 m +- 6 m (low-frequency noise),
    understory at 40 % of the stand height between crowns."""
    stand = 20.0 + 6.0 * fbm(e / 900.0, n / 900.0, seed + 31, 2, 0.5)
    d, tx, ty, _ = worley(e / 8.0, n / 8.0, seed + 37, 0.9)
    radius = 0.55 + 0.15 * uniform(tx, ty, seed + 41)
    top = stand * (0.8 + 0.3 * uniform(tx, ty, seed + 43))
    tree = hash3(tx, ty, seed + 47)
    if d >= radius:
        return 0.4 * stand, tree
    q = d / radius
    return max(top - 0.5 * top * (1.0 - math.sqrt(1.0 - q * q)), 0.4 * stand), tree


class LandCover(NamedTuple):
    """What _land_cover writes per cell of a window: `classes` (uint8, CLASSES codes), the height of the
    surface `objects` above the ground (m) and the `feature` id (int64: parcel, tree or building)."""

    classes: np.ndarray
    objects: np.ndarray
    feature: np.ndarray


@njit(cache=True, nogil=True, parallel=True)
def _land_cover(
    dtm: np.ndarray,
    slope: np.ndarray,
    water: np.ndarray,
    e0: float,
    de: float,
    n0: float,
    dn: float,
    towns: np.ndarray,
    seed: int,
    objects_on: bool,
    out: LandCover,
) -> None:
    """Per cell of `out`, from the window's orthometric `dtm`, `slope` and `water` with the local metres of
    its first cell (e0, n0) and its spacing (de, dn): WATER where `water`; CITY inside a town's noisy disc
    (slope < 15 deg); FOREST where slope + 14 fbm(1.5 km) > 13 (steep slopes and noisy patches); otherwise a
    field parcel (Worley cells of ~220 m): BARE for 35 % of the parcels, CROPS for the rest. Surface objects
    (buildings, trees) only with `objects_on`."""
    classes, objects, feature = out
    rows, cols = dtm.shape
    for i in prange(rows):
        n = n0 - i * dn
        for j in range(cols):
            e = e0 + j * de
            classes[i, j] = 0
            objects[i, j] = 0.0
            feature[i, j] = 0
            if water[i, j]:
                classes[i, j] = WATER
                continue
            town = -1
            for k in range(towns.shape[0]):
                r = math.hypot(e - towns[k, 0], n - towns[k, 1])
                if r < 1.3 * towns[k, 2] and r < towns[k, 2] * (
                    1.0 + 0.3 * gradient_noise(e / 250.0, n / 250.0, seed + 13 + k)
                ):
                    town = k
                    break
            if town >= 0 and slope[i, j] < 15.0:
                h, f = _city_cell(dtm, e, n, e0, de, n0, dn, towns[town], seed + 1000 * town)
                classes[i, j] = CITY
                feature[i, j] = f
                if objects_on:
                    objects[i, j] = h
                continue
            if slope[i, j] + 14.0 * fbm(e / 1500.0, n / 1500.0, seed + 17, 3, 0.5) > 13.0:
                h, f = _canopy(e, n, seed)
                classes[i, j] = FOREST
                feature[i, j] = f
                if objects_on:
                    objects[i, j] = h
                continue
            _, px, py, _ = worley(e / 220.0, n / 220.0, seed + 19, 0.8)
            classes[i, j] = BARE if uniform(px, py, seed + 23) < 0.35 else CROPS
            feature[i, j] = hash3(px, py, seed + 29)


@dataclass
class Terrain:
    """DTM, DSM (ellipsoidal heights, float64), land cover and per-cell feature ids on `grid`: grid
    arrays (tiles.grid_array: numpy arrays, or DiskArray files read and written by slices)."""

    grid: Grid
    dtm: object
    dsm: object
    classes: object  # uint8, CLASSES codes
    feature: object  # int64: parcel / tree / building id (see LandCover)
    towns: np.ndarray  # (k, 5): east, north, radius, angle, block size (local metres)


def check_coverage(source, bounds):
    """Raise InputError unless `bounds` lies inside the source DEM (2 cells kept for the cubic)."""
    lon0, dlon, _, lat0, _, dlat = source.geotransform
    s_lon_min, s_lat_min, s_lon_max, s_lat_max = source.bounds
    margin_lon, margin_lat = 2 * dlon, -2 * dlat
    lon_min, lat_min, lon_max, lat_max = bounds
    if (
        lon_min < s_lon_min + margin_lon
        or lon_max > s_lon_max - margin_lon
        or lat_min < s_lat_min + margin_lat
        or lat_max > s_lat_max - margin_lat
    ):
        raise InputError(
            f"the images need terrain over lon {lon_min:.4f}..{lon_max:.4f}, lat {lat_min:.4f}..{lat_max:.4f}, "
            f"but the source DEM covers lon {s_lon_min:.4f}..{s_lon_max:.4f}, lat {s_lat_min:.4f}..{s_lat_max:.4f}; "
            "make the scene smaller or move its centre"
        )


def build_terrain(source, grid, seed, fractal=1.0, surface_objects=True, folder=None, tile=TILE):
    """DTM = cubic resampling of the source + fractal detail (fBm below 180 m wavelength,
    `fractal` x 4 m), lake cells set to the water level; then land cover and surface objects;
    finally + geoid undulation, so all heights are ellipsoidal. Tile by tile (module docstring);
    the grids are arrays in memory, or files in `folder` (tiles.grid_array)."""
    shape = grid.shape
    lon0, dlon, _, lat0, _, dlat = source.geotransform
    x0 = (grid.lon0 + 0.5 * grid.dlon - lon0) / dlon - 0.5
    y0 = (grid.lat0 + 0.5 * grid.dlat - lat0) / dlat - 0.5
    sdx, sdy = grid.dlon / dlon, grid.dlat / dlat
    e0, de, n0, dn = grid.local_metres()

    def resample(src, window, kernel=cubic_resample):
        i0, i1, j0, j1 = window
        return kernel(src, x0 + j0 * sdx, sdx, y0 + i0 * sdy, sdy, i1 - i0, j1 - j0)

    octaves = max(1, int(math.floor(math.log2(FRACTAL_WAVELENGTH / (2.0 * min(de, dn))))) + 1)
    orthometric = grid_array(folder, "orthometric", shape, np.float64)
    water = grid_array(folder, "water", shape, np.bool_)
    lake = source.lake.astype(np.uint8)
    for window in windows(shape, tile):
        i0, i1, j0, j1 = window
        dtm = resample(source.heights, window)
        if fractal > 0:
            _add_fractal(
                dtm,
                e0 + j0 * de,
                de,
                n0 - i0 * dn,
                dn,
                FRACTAL_WAVELENGTH,
                octaves,
                fractal * FRACTAL_AMPLITUDE,
                FRACTAL_PERSISTENCE,
                seed + 3,
            )
        wet = (resample(lake, window, _nearest) > 0) & (dtm <= LAKE_LEVEL)
        dtm[wet] = LAKE_LEVEL
        orthometric[i0:i1, j0:j1] = dtm
        water[i0:i1, j0:j1] = wet
    slope = grid_array(folder, "slope", shape, np.float32)
    for window in windows(shape, tile):
        outer, inner = grown(window, shape, 1)
        i0, i1, j0, j1 = window
        slope[i0:i1, j0:j1] = slope_degrees(cut(orthometric, outer), de, dn)[inner]
    towns = _place_towns(slope, water, grid, seed)
    classes = grid_array(folder, "classes", shape, np.uint8)
    feature = grid_array(folder, "feature", shape, np.int64)
    dtm = grid_array(folder, "dtm", shape, np.float64)
    dsm = grid_array(folder, "dsm", shape, np.float64)
    margin = int(math.ceil(CITY_REACH_M / min(de, dn))) + 2
    for window in windows(shape, tile):
        outer, inner = grown(window, shape, margin)
        i0, i1, j0, j1 = window
        z = cut(orthometric, outer)
        c = np.empty(z.shape, np.uint8)
        objects = np.empty(z.shape, np.float64)
        f = np.empty(z.shape, np.int64)
        _land_cover(
            z,
            cut(slope, outer),
            cut(water, outer),
            e0 + outer[2] * de,
            de,
            n0 - outer[0] * dn,
            dn,
            towns,
            seed,
            bool(surface_objects),
            LandCover(c, objects, f),
        )
        ground = z[inner] + resample(source.geoid, window)
        dtm[i0:i1, j0:j1] = ground
        dsm[i0:i1, j0:j1] = ground + objects[inner]
        classes[i0:i1, j0:j1] = c[inner]
        feature[i0:i1, j0:j1] = f[inner]
    release(orthometric, water, slope)
    return Terrain(grid, dtm, dsm, classes, feature, towns)


@njit(cache=True, nogil=True, parallel=True)
def _nearest(src, x0, dx, y0, dy, rows, cols):
    """Nearest-neighbour resampling at source vertex coordinates x0 + j dx, y0 + i dy."""
    out = np.empty((rows, cols), src.dtype)
    sr, sc = src.shape
    for i in prange(rows):
        m = min(max(int(round(y0 + i * dy)), 0), sr - 1)
        for j in range(cols):
            out[i, j] = src[m, min(max(int(round(x0 + j * dx)), 0), sc - 1)]
    return out


def _place_towns(slope, water, grid, seed):
    """Town discs (east, north, radius, angle, block) on the flattest dry ground of the inner
    60 % of the grid: one per 150 km^2 (at least one), radius 12 % of the grid's size
    (250-900 m), at least 3 radii apart."""
    rng = np.random.default_rng([seed, 7])
    de, dn = grid.cell_metres
    size = min(grid.rows * dn, grid.cols * de)
    count = max(1, int(round(grid.rows * dn * grid.cols * de / 150e6)))
    radius = float(np.clip(0.12 * size, 250.0, 900.0))
    k = max(1, int(round(radius / (2 * min(de, dn)))))
    rows, cols = (grid.rows // k) * k, (grid.cols // k) * k
    coarse = np.empty((rows // k, cols // k), np.float32)
    wet = np.empty((rows // k, cols // k), bool)
    for b in range(rows // k):  # one band of blocks at a time (the grids may be files)
        coarse[b] = slope[b * k : (b + 1) * k, :cols].reshape(k, cols // k, k).mean(axis=(0, 2))
        wet[b] = water[b * k : (b + 1) * k, :cols].reshape(k, cols // k, k).any(axis=(0, 2))
    ci, cj = np.mgrid[0 : coarse.shape[0], 0 : coarse.shape[1]]
    yc, xc = (ci + 0.5) * k, (cj + 0.5) * k
    inner = (np.abs(yc / grid.rows - 0.5) < 0.3) & (np.abs(xc / grid.cols - 0.5) < 0.3)
    score = np.where(inner & ~wet, coarse + rng.uniform(0.0, 1.0, coarse.shape), np.inf)
    e0, _, n0, _ = grid.local_metres()
    towns = []
    for flat in np.argsort(score, axis=None):
        if not np.isfinite(score.flat[flat]) or len(towns) == count:
            break
        e = e0 + xc.flat[flat] * de
        n = n0 - yc.flat[flat] * dn
        if all(np.hypot(e - t[0], n - t[1]) > 3 * radius for t in towns):
            towns.append((e, n, radius, rng.uniform(0, np.pi / 2), rng.uniform(70.0, 110.0)))
    return np.array(towns, dtype=np.float64).reshape(-1, 5)
