"""simulate_scene: one call from configuration to a folder of simulated SPOT products and their
truth (the entry point of the Processing algorithm pushbroom:simulatescene).

Folder layout (written atomically: a cancel or an error leaves nothing under `out_dir`):

    <image>/IMAGERY.TIF, <image>/METADATA.DIM   level-1A product, the *supplied* orientation
                                                 (truth perturbed by known errors)
    truth/<image>/METADATA.DIM                   the exact orientation, sampled from the truth
    truth/truth.json                             configuration, injected corrections (Corrections
                                                 convention), sun, B/H, footprint rays, legend
    dsm.tif, dtm.tif                             ellipsoidal heights (float32, EPSG:4326 grid)
    classes.tif                                  land cover (uint8, terrain.CLASSES)
    orthoimage.tif                               ground radiance, nominal gain, 8 bit
    points.csv                                   control/check point candidates (outputs.write_points)

Memory follows tiles, not the scene: the ground grids are files in a work folder inside the output
being built (tiles.py), the terrain, radiance and PSF filter run per ground tile, and each image is
rendered in bands of BAND lines, cast in windows (tiled_surface.py) and written band by band. A
full-size SPOT 5 triplet (60 km: HRG 12 000 x 12 000 px) thus fits a small machine.
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..atomic import atomic_dir
from ..dem import Dem
from ..errors import GeometryError, InputError, MetadataError
from ..geodesy import geodetic_to_ecef, metres_per_degree
from ..progress import step, warn
from ..sensors.dimap import read_dimap
from ..sensors.dimap_writer import write_dimap
from ..sensors.spot_orientation import Corrections
from ..surface.geotiff import to_cog
from . import outputs, radiometry
from .acquisition import footprint_bounds, plan, ray_at_height
from .grid import Grid
from .instruments import CONFIGURATIONS, DEFAULT_DATES, DEFAULT_ROLL_DEG, instruments
from .perturbation import inject
from .points import Candidates, ground_heights, image_coordinates, level_pads, select_sites, shortfall, site_spacing
from .render import BLOCK, block_max
from .sun import sun_position
from .terrain import CLASSES, FOREST, Terrain, build_terrain, check_coverage, extended_dem, jacksboro_dem
from .tiled_surface import TiledSurface
from .tiles import TILE, cut, grid_array, grown, value_range, windows
from .truth import ImageTruth

#: the ground rasters of a scene (GeoTIFFs in EPSG:4326), by their key in the paths simulate_scene returns
GROUND_RASTERS = ("dsm", "dtm", "classes", "orthoimage")

#: the truth file, relative to the scene folder: it marks a folder simulate_scene made (and may replace)
TRUTH = os.path.join("truth", "truth.json")
TERRAIN_MARGIN_M = 400.0  # ground beyond the images' footprints (shadows, pads)
OBJECT_MAX_M = 60.0  # highest surface object, for the footprint bounds
MARKER_SIGMA_M = 10.0  # Gaussian marker sigma: 1 px of the coarsest (10 m) images
CLEARANCE_M = 40.0  # open ground around a point candidate without markers
BITS = (8, 12)  # radiometric resolutions of the simulated imagery
SIZE_KM = (1.0, 60.0)  # scene sizes: up to a full SPOT scene (60 km swath)
BAND = 256  # image lines rendered, noised and written at a time


@dataclass
class SceneConfig:
    """Simulation parameters (each maps to a parameter of pushbroom:simulatescene)."""

    configuration: str = "spot5_triplet"  # 'spot5_triplet' | 'spot14_pair' (instruments.py)
    size_km: float = 20.0  # scene width and height
    seed: int = 1  # same seed, same bytes
    bits: int = 8  # 8 or 12 bit imagery
    noise: float = 1.0  # image noise sigma, DN at 8 bit (scaled for 12 bit)
    fractal: float = 1.0  # fractal terrain detail (x 4 m; 0 = off)
    surface_objects: bool = True  # forest canopy and buildings in the DSM
    points: int = 30  # control/check point candidates wanted
    blunders: int = 0  # gross errors among the simulated measurements
    measurement_sigma: float = 0.3  # px, noise of the simulated measurements
    markers: bool = False  # bright targets painted at the point candidates
    look_table: str = ""  # METADATA.DIM whose look-angle table and line period to use
    orthoimage: str = ""  # raster to use as ground reflectance (procedural if empty)
    error_scale: float = 1.0  # scale of the injected orientation errors (0: supplied = truth)
    grid_m: float = 5.0  # ground grid (DTM, DSM, radiance) cell, m
    centre_lon: float | None = None  # scene centre (default: the DEM's centre)
    centre_lat: float | None = None
    roll_deg: tuple = ()  # per pass, across-track viewing angle (default per configuration)
    dates: tuple = ()  # per pass, ISO dates (default per configuration)

    @classmethod
    def small(cls, **overrides):
        """A 3 x 3 km scene for fast tests, in the valley south-east of Pine Mountain: fields, a
        town and the forested escarpment."""
        return cls(**{"size_km": 3.0, "points": 9, "centre_lon": -84.19, "centre_lat": 36.617, **overrides})

    def resolved(self):
        """A validated copy with the per-configuration defaults filled in; raises InputError.
        `roll_deg` and `dates` may also be comma-separated text ("12,-12")."""
        if self.configuration not in CONFIGURATIONS:
            raise InputError(f"configuration must be one of {', '.join(CONFIGURATIONS)}, not {self.configuration!r}")
        if isinstance(self.roll_deg, str) or isinstance(self.dates, str):
            return dataclasses.replace(
                self, roll_deg=_split(self.roll_deg, float, "roll angle"), dates=_split(self.dates, str, "date")
            ).resolved()
        passes = len(DEFAULT_DATES[self.configuration])
        checks = [
            (int(self.seed) == self.seed and 0 <= self.seed < 2**31, f"seed {self.seed} is not an integer 0..2^31-1"),
            (
                SIZE_KM[0] <= self.size_km <= SIZE_KM[1],
                f"scene size {self.size_km} km is outside {SIZE_KM[0]:g}..{SIZE_KM[1]:g} km (a full SPOT scene)",
            ),
            (self.bits in BITS, f"bits must be 8 or 12, not {self.bits}"),
            (0.0 <= self.noise <= 50.0, f"noise {self.noise} DN is outside 0..50"),
            (0.0 <= self.fractal <= 5.0, f"fractal detail {self.fractal} is outside 0..5"),
            (0 <= self.points <= 400, f"points {self.points} is outside 0..400"),
            (self.blunders >= 0, f"blunders {self.blunders} must not be negative"),
            (0.0 <= self.measurement_sigma <= 5.0, f"measurement sigma {self.measurement_sigma} px is outside 0..5"),
            (0.0 <= self.error_scale <= 10.0, f"error scale {self.error_scale} is outside 0..10"),
            (1.0 <= self.grid_m <= 20.0, f"ground grid {self.grid_m} m is outside 1..20 m"),
            ((self.centre_lon is None) == (self.centre_lat is None), "give both centre_lon and centre_lat, or neither"),
            (
                len(self.roll_deg) in (0, passes),
                f"{self.configuration} needs {passes} roll angle(s), got {len(self.roll_deg)}",
            ),
            (len(self.dates) in (0, passes), f"{self.configuration} needs {passes} date(s), got {len(self.dates)}"),
            (
                all(abs(r) <= 27.0 for r in self.roll_deg),
                "roll angles must lie within +-27 degrees (the SPOT mirror range)",
            ),
            (
                not self.look_table or os.path.isfile(self.look_table),
                f"look-angle table {self.look_table!r} is not a file",
            ),
            (not self.orthoimage or os.path.isfile(self.orthoimage), f"orthoimage {self.orthoimage!r} is not a file"),
        ]
        for ok, message in checks:
            if not ok:
                raise InputError(message)
        dates = tuple(self.dates) or DEFAULT_DATES[self.configuration]
        for date in dates:
            try:
                np.datetime64(date, "D")
            except ValueError:
                raise InputError(f"date {date!r} is not an ISO date (YYYY-MM-DD)") from None
        roll = self.roll_deg or DEFAULT_ROLL_DEG[self.configuration]
        return dataclasses.replace(
            self, seed=int(self.seed), dates=tuple(str(d) for d in dates), roll_deg=tuple(float(r) for r in roll)
        )


def _split(value, kind, what):
    """Tuple of `kind` from comma-separated text (tuples pass through)."""
    if not isinstance(value, str):
        return tuple(value)
    try:
        return tuple(kind(v.strip()) for v in value.split(",") if v.strip())
    except ValueError:
        raise InputError(f"cannot read the {what}s {value!r}: give comma-separated values") from None


def _look_table(config):
    """(psi_x, psi_y, line_period) of config.look_table, checked against the configuration."""
    if not config.look_table:
        return None
    try:
        o = read_dimap(config.look_table)
    except MetadataError as exc:
        raise InputError(f"cannot use {config.look_table} as look-angle table: {exc}") from exc
    wanted = instruments(config.configuration)[0].mission
    if (o.mission == 5) != (wanted == 5):
        raise InputError(
            f"{config.look_table} is a SPOT {o.mission} scene; {config.configuration} needs a "
            f"{'SPOT 5' if wanted == 5 else 'SPOT 1-4'} look-angle table"
        )
    return o.psi_x, o.psi_y, o.line_period


def simulate_scene(config, out_dir, feedback=None, tile=TILE, cog=False):
    """Simulate the scene of `config` into the folder `out_dir` (replaced as a whole) and return
    the paths written: {'folder', 'images': {name: {'imagery', 'metadata'}}, 'truth_metadata':
    {name: path}, 'truth', 'dsm', 'dtm', 'classes', 'orthoimage', 'points'}. `tile`: the ground
    tile side in cells (the products do not depend on it). Where `cog`, the ground rasters (dsm, dtm,
    classes, orthoimage) are Cloud-Optimised GeoTIFFs (surface.geotiff.to_cog); the level-1A imagery
    stays the plain TIFF of a DIMAP product."""
    config = config.resolved()
    step(feedback, 0, f"planning the {config.configuration} acquisition")
    source = extended_dem(jacksboro_dem())
    images, grid, centre = _plan(config, source)
    with atomic_dir(out_dir) as tmp:
        work = os.path.join(tmp, "ground")
        os.mkdir(work)
        step(feedback, 5, f"building the terrain ({grid.cols} x {grid.rows} cells of {config.grid_m:g} m)")
        terrain = build_terrain(source, grid, config.seed, config.fractal, config.surface_objects, work, tile)
        step(feedback, 20, "choosing control/check point candidates")
        candidates, surface = _candidates(config, terrain, images, work, tile, feedback)
        step(feedback, 30, "computing the ground radiance")
        radiance, suns = _radiance(config, terrain, surface, images, candidates, centre, work, tile)
        corrections, trajectory = inject(images, np.random.default_rng([config.seed, 3]), config.error_scale)
        paths = _products(tmp, images)
        radiometric, footprints = {}, {}
        for k, image in enumerate(images):
            start, span = 40 + 45 * k / len(images), 45 / len(images)
            step(feedback, start, f"rendering {image.name} ({image.ncols} x {image.nrows})")
            filtered = grid_array(work, "filtered", grid.shape, np.float32)
            ground_psf_filter(
                image, grid, 0.5 * (surface.hmin + surface.hmax), radiance[image.instrument.pass_index], filtered, tile
            )
            radiometric[image.name] = _render(
                config, image, surface, filtered, k, paths["images"][image.name]["imagery"], feedback, (start, span)
            )
            footprints[image.name] = _footprint(image, surface)
        step(feedback, 85, "writing the products")
        _write(
            paths,
            _Simulated(
                config,
                images,
                terrain,
                radiance[0],
                candidates,
                corrections,
                trajectory,
                suns,
                radiometric,
                footprints,
                geodetic_to_ecef(*centre),
            ),
        )
        shutil.rmtree(work)
        if cog:
            for k, name in enumerate(GROUND_RASTERS):
                step(feedback, 95 + k, f"{name} as a Cloud-Optimised GeoTIFF")
                to_cog(paths[name])
    step(feedback, 100)
    return _rebase(paths, tmp, os.path.abspath(os.fspath(out_dir)))


def _plan(config, source):
    """Images over the scene centre (lon, lat, h) and the ground grid covering their footprints
    (heights from the DEM's lowest to its highest plus objects, TERRAIN_MARGIN_M around)."""
    lon_c, lat_c = source.centre if config.centre_lon is None else (config.centre_lon, config.centre_lat)
    lon_min, lat_min, lon_max, lat_max = source.bounds
    if not (lon_min < lon_c < lon_max and lat_min < lat_c < lat_max):
        raise InputError(
            f"the scene centre ({lon_c:.4f}, {lat_c:.4f}) lies outside the source DEM "
            f"(lon {lon_min:.4f}..{lon_max:.4f}, lat {lat_min:.4f}..{lat_max:.4f})"
        )
    source_dem = Dem(source.heights + source.geoid, source.geotransform)
    centre = (lon_c, lat_c, source_dem.height(lon_c, lat_c))
    images = plan(
        config.configuration,
        centre,
        config.size_km * 1000.0,
        config.dates,
        config.roll_deg,
        np.random.default_rng([config.seed, 1]),
        _look_table(config),
    )
    low, high = source.planning_range
    bounds = footprint_bounds(images, (low - 10.0, high + OBJECT_MAX_M))
    me, mn = metres_per_degree(lat_c)
    bounds = (
        bounds[0] - TERRAIN_MARGIN_M / me,
        bounds[1] - TERRAIN_MARGIN_M / mn,
        bounds[2] + TERRAIN_MARGIN_M / me,
        bounds[3] + TERRAIN_MARGIN_M / mn,
    )
    check_coverage(source, bounds)
    return images, Grid.covering(bounds, config.grid_m), centre


def _candidates(config, terrain, images, folder=None, tile=TILE, feedback=None):
    """Point candidates (pads levelled under markers first) and the ray-casting surface; a warning where the
    scene holds fewer candidates or blunders than asked (points.shortfall)."""
    rng = np.random.default_rng([config.seed, 2])
    pad = 5.0 * MARKER_SIGMA_M
    clearance = 1.5 * pad + 30.0 if config.markers else CLEARANCE_M
    sites = select_sites(terrain, images, config.points, clearance, rng, folder=folder, tile=tile)
    if config.markers and len(sites):
        level_pads(terrain, sites[:, 0], sites[:, 1], pad)
    surface = TiledSurface(terrain.grid, terrain.dsm, value_range(terrain.dsm, terrain.grid.shape, tile))
    heights = ground_heights(terrain.dtm, terrain.grid, sites[:, 0], sites[:, 1])
    candidates = image_coordinates(sites, heights, images, surface, config.measurement_sigma, config.blunders, rng)
    spacing_m = site_spacing(terrain.grid, config.points) * float(np.mean(terrain.grid.cell_metres))
    warn(feedback, shortfall(config.points, len(sites), candidates, config.blunders, spacing_m, clearance))
    return candidates, surface


def _radiance(config, terrain, surface, images, candidates, centre, folder=None, tile=TILE):
    """Ground radiance of each pass ({pass: grid array}) and its sun (azimuth, elevation) in
    degrees, tile by tile; each tile's shadows are cast in a window reaching the highest ground."""
    grid = terrain.grid
    e0, de, n0, dn = grid.local_metres()
    suns = {}
    for image in images:
        key = image.instrument.pass_index
        if key not in suns:
            when = image.epoch + np.timedelta64(int(round(image.centre_time * 1e9)), "ns")
            suns[key] = sun_position(when, centre[0], centre[1])
    user = radiometry.OrthoimageReflectance(config.orthoimage, grid) if config.orthoimage else None
    radiance = {key: grid_array(folder, f"radiance-{key}", grid.shape, np.float32) for key in suns}
    sun_rad = {key: (math.radians(azimuth), math.radians(elevation)) for key, (azimuth, elevation) in suns.items()}
    relief = surface.hmax - surface.hmin + 0.05
    margins = [radiometry.sun_margins(de, dn, az, el, relief) for az, el in sun_rad.values()]
    margins = [max(m[side] for m in margins) for side in range(4)]  # one DSM window serves every sun
    for window in windows(grid.shape, tile):
        i0, i1, j0, j1 = window
        outer, inner = grown(window, grid.shape, *margins)
        z = cut(terrain.dsm, outer)
        if user:
            rho = user(window)
        else:
            rho = radiometry.reflectance(
                cut(terrain.classes, window),
                cut(terrain.feature, window),
                z[inner] - cut(terrain.dtm, window),
                e0 + j0 * de,
                de,
                n0 - i0 * dn,
                dn,
                config.seed,
            )
        if config.markers:
            radiometry.paint_markers(rho, grid, candidates.lon, candidates.lat, MARKER_SIGMA_M, origin=(i0, j0))
        bmax = block_max(z, BLOCK)
        for key, (az, el) in sun_rad.items():
            light = radiometry.illumination(
                z, bmax, de, dn, az, el, surface.hmax, inner[0].start, inner[0].stop, inner[1].start, inner[1].stop
            )
            radiance[key][i0:i1, j0:j1] = rho * light
    return radiance, suns


def _render(config, image, surface, filtered, index, path, feedback=None, progress=(0, 0)):
    """Render the DN image of one instrument into `path`, BAND lines at a time, with its gain
    (nominal +-8 %) and offset (+-30 %); the noise of consecutive bands continues one random stream."""
    rng = np.random.default_rng([config.seed, 10 + index])
    gain = radiometry.NOMINAL_GAIN * (1.0 + rng.normal(0.0, 0.08))
    offset = radiometry.NOMINAL_OFFSET * (1.0 + rng.normal(0.0, 0.3))
    look = image.look_vectors()
    with outputs.imagery_writer(path, image.ncols, image.nrows, config.bits) as write:
        for a in range(0, image.nrows, BAND):
            step(feedback, progress[0] + progress[1] * a / image.nrows)
            b = min(a + BAND, image.nrows)
            sample = surface.render(*image.line_geometry(np.arange(a, b) + 0.5), look, filtered)
            if np.isnan(sample).any():
                raise GeometryError(
                    f"{np.isnan(sample).sum()} rays of {image.name} (lines {a}..{b - 1}) miss the simulated terrain"
                )
            write(radiometry.sensor_image(sample, gain, offset, config.noise, config.bits, rng), a)
    return {"gain": gain, "offset": offset}


def ground_psf_jacobian(image, grid, h, d=16.0):
    """2 x 2 d(grid x, grid y)/d(col, row) at the image centre on the flat surface of height h
    (central differences over +-d px: the pixel's footprint on the ground grid)."""
    c0, r0 = 0.5 * image.ncols, 0.5 * image.nrows
    cols = np.array([c0 - d, c0 + d, c0, c0])
    rows = np.array([r0, r0, r0 - d, r0 + d])
    pos, mat = image.line_geometry(rows)
    direction = np.einsum("nij,nj->ni", mat.reshape(-1, 3, 3), image.look_vectors(cols))
    x, y = grid.vertex(*ray_at_height(pos, direction, h))
    return np.array([[x[1] - x[0], x[3] - x[2]], [y[1] - y[0], y[3] - y[2]]]) / (2.0 * d)


def ground_psf_filter(image, grid, height, radiance, out=None, tile=TILE, pad=64):
    """The ground radiance convolved with the image's PSF projected onto the ground grid, so that
    one ray per pixel sampling it equals the PSF integral of the pixel (radiometry module
    docstring) on locally flat ground. The PSF is separable in (detector, line) with transfer
    function Hc(u) Hr(v), u, v in cycles per detector / line:
      Hc(u) = sinc(u) exp(-2 pi^2 s^2 u^2),  Hr(v) = sinc(n v) sinc(v) exp(-2 pi^2 (s n)^2 v^2)
    (s = OPTICS_SIGMA, n = detector_lines, the line smear box of 1 line); with J the pixel -> grid
    Jacobian (ground_psf_jacobian at `height`, the mean DSM height), a ground frequency k (cycles per cell)
    is (u, v) = J^T k, so the filter is exact (analytic, oriented, elongated along track off
    nadir) for the band-limited grid. Relief changes the footprint only through J: a slope or a
    height off the mean rescales it by a few % (second order in the image, see _integrate), J's
    drift across the swath (view angle) likewise. Tile by tile into `out` (a grid array, in memory
    if None): each tile is filtered with `pad` cells of its neighbours (the PSF's support is a few
    cells), reflect-padded at the grid's edges."""
    out = np.empty(grid.shape, np.float32) if out is None else out
    jac = ground_psf_jacobian(image, grid, height)
    for window in windows(grid.shape, tile):
        outer, _ = grown(window, grid.shape, pad)
        a0, a1, b0, b1 = outer
        i0, i1, j0, j1 = window
        data = np.pad(
            cut(radiance, outer).astype(np.float32),
            ((pad - (i0 - a0), pad - (a1 - i1)), (pad - (j0 - b0), pad - (b1 - j1))),
            mode="reflect",
        )
        out[i0:i1, j0:j1] = _psf_filtered(data, jac, image.instrument)[pad : pad + i1 - i0, pad : pad + j1 - j0]
    return out


def _psf_filtered(data, jac, ins):
    """`data` convolved with the PSF of instrument `ins` under the pixel -> grid Jacobian `jac`
    (ground_psf_filter), by FFT."""
    from scipy import fft

    shape = [fft.next_fast_len(n, real=True) for n in data.shape]
    ky = fft.fftfreq(shape[0])[:, None]
    kx = fft.rfftfreq(shape[1])[None, :]
    u = jac[0, 0] * kx + jac[1, 0] * ky
    v = jac[0, 1] * kx + jac[1, 1] * ky
    s, n = radiometry.OPTICS_SIGMA, ins.detector_lines
    two_pi2 = 2.0 * math.pi**2
    tf = (
        np.sinc(u)
        * np.exp(-two_pi2 * s * s * u * u)
        * np.sinc(n * v)
        * np.sinc(v)
        * np.exp(-two_pi2 * (s * n) ** 2 * v * v)
    ).astype(np.float32)
    del u, v
    spec = fft.rfft2(data, s=shape, workers=-1)
    spec *= tf
    del tf
    return fft.irfft2(spec, s=shape, workers=-1)[: data.shape[0], : data.shape[1]].astype(np.float32)


def _integrate(image, surface, radiance, k=radiometry.SUPERSAMPLE, block=128):
    """Radiance integrated over each pixel's PSF (radiometry module docstring): rays on a 1/k px
    lattice (its centre rays are the pixel centres'), the separable quadrature weights of
    radiometry.psf_kernel, every k-th sample kept; row blocks bound the memory."""
    ins = image.instrument
    wc = radiometry.psf_kernel(1.0, 0.0, radiometry.OPTICS_SIGMA, k)
    wr = radiometry.psf_kernel(ins.detector_lines, 1.0, radiometry.OPTICS_SIGMA * ins.detector_lines, k)
    mc, mr = len(wc) // 2, len(wr) // 2
    cols = 0.5 + np.arange(-mc, (image.ncols - 1) * k + mc + 1) / k
    look = image.look_vectors(cols)
    out = np.empty((image.nrows, image.ncols), np.float32)
    for a in range(0, image.nrows, block):
        b = min(a + block, image.nrows)
        rows = a + 0.5 + np.arange(-mr, (b - a - 1) * k + mr + 1) / k
        pos, mat = image.line_geometry(rows)
        fine = surface.render(pos, mat, look, radiance).astype(np.float64)
        fine = _correlate_valid(fine, wc, axis=1)[:, ::k]
        out[a:b] = _correlate_valid(fine, wr, axis=0)[::k]
    return out


def _correlate_valid(a, w, axis):
    """sum_m w[m] a[i + m] along `axis` over the positions where the kernel fits."""
    n = a.shape[axis] - len(w) + 1
    out = np.zeros(a.shape[:axis] + (n,) + a.shape[axis + 1 :])
    for m, wm in enumerate(w):
        out += wm * (a[:, m : m + n] if axis == 1 else a[m : m + n])
    return out


def _footprint(image, surface):
    """Ground points of the rays of the corner and centre pixel centres."""
    cols = np.array([0.5, image.ncols - 0.5, image.ncols - 0.5, 0.5, 0.5 * image.ncols])
    rows = np.array([0.5, 0.5, image.nrows - 0.5, image.nrows - 0.5, image.centre_row])
    pos, mat = image.line_geometry(rows)
    ground = surface.trace(pos, mat, image.look_vectors(cols))
    return [{"col": c, "row": r, "lon": g[0], "lat": g[1], "h": g[2]} for c, r, g in zip(cols, rows, ground)]


def _products(folder, images):
    """The product folders of the images and the paths of their files (written later)."""
    join = os.path.join
    paths = {"folder": folder, "images": {}, "truth_metadata": {}}
    for image in images:
        os.makedirs(join(folder, image.name))
        os.makedirs(join(folder, "truth", image.name))
        paths["images"][image.name] = {
            "imagery": join(folder, image.name, "IMAGERY.TIF"),
            "metadata": join(folder, image.name, "METADATA.DIM"),
        }
        paths["truth_metadata"][image.name] = join(folder, "truth", image.name, "METADATA.DIM")
    return paths


@dataclass
class _Simulated:
    """What simulate_scene computed that the products besides the imagery (_write) and the truth file
    (_truth) hold: the scene's images, terrain, the first pass's ground radiance (a grid array), the point
    candidates, the injected corrections (per image name) and trajectory errors (per pass), the suns (per
    pass: azimuth, elevation in degrees), each image's gain and offset and footprint rays, and the ECEF
    position of the scene centre."""

    config: SceneConfig
    images: list[ImageTruth]
    terrain: Terrain
    radiance: Any
    candidates: Candidates
    corrections: dict[str, Corrections]
    trajectory: dict[int, dict[str, Any]]
    suns: dict[int, tuple[float, float]]
    radiometric: dict[str, dict[str, float]]
    footprints: dict[str, list[dict[str, float]]]
    centre: np.ndarray


def _write(paths: dict[str, Any], simulated: _Simulated) -> dict[str, Any]:
    """Everything `simulated` but the imagery into the folder of `paths` (its entries added)."""
    config, images, terrain, suns = simulated.config, simulated.images, simulated.terrain, simulated.suns
    corrections, candidates, radiance = simulated.corrections, simulated.candidates, simulated.radiance
    join, folder = os.path.join, paths["folder"]
    for image in images:
        sun = suns[image.instrument.pass_index]
        write_dimap(
            paths["images"][image.name]["metadata"],
            image.orientation(corrections[image.name]),
            sun=sun,
            nbits=config.bits,
        )
        write_dimap(paths["truth_metadata"][image.name], image.orientation(), sun=sun, nbits=config.bits)
    grid = terrain.grid
    heights = {"HEIGHTS": "ellipsoidal, WGS 84 (EPSG:4979), metres"}
    for name, array, description in (("dsm", terrain.dsm, "DSM"), ("dtm", terrain.dtm, "DTM")):
        paths[name] = join(folder, f"{name}.tif")
        outputs.write_raster(paths[name], array, grid, np.float32, description=description, metadata=heights)
    paths["classes"] = join(folder, "classes.tif")
    outputs.write_raster(
        paths["classes"],
        terrain.classes,
        grid,
        np.uint8,
        nodata=0,
        description="land cover",
        metadata={f"CLASS_{k}": v for k, v in CLASSES.items() if k},
    )
    paths["orthoimage"] = join(folder, "orthoimage.tif")
    outputs.write_raster(
        paths["orthoimage"], radiance, grid, np.uint8, description="ground radiance", convert=radiometry.orthoimage
    )
    paths["points"] = join(folder, "points.csv")
    outputs.write_points(paths["points"], candidates)
    paths["truth"] = join(folder, TRUTH)
    outputs.write_json(paths["truth"], _truth(simulated))
    return paths


def _truth(simulated: _Simulated) -> dict[str, Any]:
    """The content of the truth file (module docstring) of `simulated`."""
    config, images, corrections, suns = simulated.config, simulated.images, simulated.corrections, simulated.suns
    radiometric, footprints, terrain = simulated.radiometric, simulated.footprints, simulated.terrain
    config_dict = dataclasses.asdict(config)
    per_image = {}
    for image in images:
        c = corrections[image.name]
        per_image[image.name] = {
            "mission": image.instrument.mission,
            "instrument": image.instrument.instrument,
            "instrument_index": image.instrument.instrument_index,
            "pass": image.instrument.pass_index,
            "size": [image.ncols, image.nrows],
            "epoch": str(image.epoch),
            "centre_time": image.centre_time,
            "centre_row": image.centre_row,
            "line_period": image.instrument.line_period,
            "sun_azimuth_elevation": suns[image.instrument.pass_index],
            "corrections": {"position": c.position, "attitude": c.attitude, "look": c.look, "time_scale": c.time_scale},
            "radiometry": radiometric[image.name],
            "footprint": footprints[image.name],
        }
    return {
        "config": config_dict,
        "images": per_image,
        "trajectory_errors": simulated.trajectory,
        "base_to_height": _base_to_height(images, simulated.centre),
        "classes": {str(k): v for k, v in CLASSES.items()},
        "towns": terrain.towns,
        "forest_fraction": _fraction(terrain.classes, terrain.grid.shape, FOREST),
        "grid": {
            "geotransform": terrain.grid.geotransform,
            "size": [terrain.grid.cols, terrain.grid.rows],
            "crs": "EPSG:4326, heights ellipsoidal (WGS 84)",
        },
        "conventions": "image (col, row): GDAL, (0, 0) top-left corner of the first pixel; truth = supplied "
        "+ corrections (spot_orientation.Corrections, tau about each image's centre_time); "
        "look[0] psi_x, look[1] psi_y",
    }


def _fraction(classes, shape, code):
    """Fraction of the cells of class `code`, tile by tile."""
    return float(sum(np.count_nonzero(cut(classes, w) == code) for w in windows(shape)) / (shape[0] * shape[1]))


def _base_to_height(images, centre):
    """B/H of every image pair: |P_i - P_j| over the mean radial height |P| - |G| of the
    satellites above the scene centre G, P at the time each image sees G."""
    out = {}
    for i, a in enumerate(images):
        for b in images[i + 1 :]:
            pa, _ = a.orbit.state(a.centre_time)
            pb, _ = b.orbit.state(b.centre_time)
            height = 0.5 * (np.linalg.norm(pa) + np.linalg.norm(pb)) - np.linalg.norm(centre)
            out[f"{a.name}-{b.name}"] = float(np.linalg.norm(pa - pb) / height)
    return out


def _rebase(value, old, new):
    """`value` with the temporary folder prefix `old` replaced by `new`."""
    if isinstance(value, dict):
        return {k: _rebase(v, old, new) for k, v in value.items()}
    return new + value[len(old) :] if isinstance(value, str) and value.startswith(old) else value
