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
"""
import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..atomic import atomic_dir
from ..dem import Dem
from ..errors import GeometryError, InputError, MetadataError
from ..geodesy import geodetic_to_ecef, metres_per_degree
from ..progress import step
from ..sensors.dimap import read_dimap
from ..sensors.dimap_writer import write_dimap
from . import outputs, radiometry
from .acquisition import footprint_bounds, plan, ray_at_height
from .grid import Grid
from .instruments import CONFIGURATIONS, DEFAULT_DATES, DEFAULT_ROLL_DEG, instruments
from .perturbation import inject
from .points import image_coordinates, level_pads, select_sites
from .render import Surface
from .sun import sun_position
from .terrain import CLASSES, FOREST, build_terrain, check_coverage, jacksboro_dem

TERRAIN_MARGIN_M = 400.0    # ground beyond the images' footprints (shadows, pads)
OBJECT_MAX_M = 60.0         # highest surface object, for the footprint bounds
MARKER_SIGMA_M = 10.0       # Gaussian marker sigma: 1 px of the coarsest (10 m) images
CLEARANCE_M = 40.0          # open ground around a point candidate without markers
BITS = (8, 12)              # radiometric resolutions of the simulated imagery


@dataclass
class SceneConfig:
    """Simulation parameters (each maps to a parameter of pushbroom:simulatescene)."""

    configuration: str = "spot5_triplet"   # 'spot5_triplet' | 'spot14_pair' (instruments.py)
    size_km: float = 20.0                  # scene width and height
    seed: int = 1                          # same seed, same bytes
    bits: int = 8                          # 8 or 12 bit imagery
    noise: float = 1.0                     # image noise sigma, DN at 8 bit (scaled for 12 bit)
    fractal: float = 1.0                   # fractal terrain detail (x 4 m; 0 = off)
    surface_objects: bool = True           # forest canopy and buildings in the DSM
    points: int = 30                       # control/check point candidates wanted
    blunders: int = 0                      # gross errors among the simulated measurements
    measurement_sigma: float = 0.3         # px, noise of the simulated measurements
    markers: bool = False                  # bright targets painted at the point candidates
    look_table: str = ""                   # METADATA.DIM whose look-angle table and line period to use
    orthoimage: str = ""                   # raster to use as ground reflectance (procedural if empty)
    error_scale: float = 1.0               # scale of the injected orientation errors (0: supplied = truth)
    grid_m: float = 5.0                    # ground grid (DTM, DSM, radiance) cell, m
    centre_lon: Optional[float] = None     # scene centre (default: the DEM's centre)
    centre_lat: Optional[float] = None
    roll_deg: tuple = ()                   # per pass, across-track viewing angle (default per configuration)
    dates: tuple = ()                      # per pass, ISO dates (default per configuration)

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
            return dataclasses.replace(self, roll_deg=_split(self.roll_deg, float, "roll angle"),
                                       dates=_split(self.dates, str, "date")).resolved()
        passes = len(DEFAULT_DATES[self.configuration])
        checks = [
            (int(self.seed) == self.seed and 0 <= self.seed < 2 ** 31, f"seed {self.seed} is not an integer 0..2^31-1"),
            (1.0 <= self.size_km <= 25.0, f"scene size {self.size_km} km is outside 1..25 km (the DEM is 30 km wide)"),
            (self.bits in BITS, f"bits must be 8 or 12, not {self.bits}"),
            (0.0 <= self.noise <= 50.0, f"noise {self.noise} DN is outside 0..50"),
            (0.0 <= self.fractal <= 5.0, f"fractal detail {self.fractal} is outside 0..5"),
            (0 <= self.points <= 400, f"points {self.points} is outside 0..400"),
            (self.blunders >= 0, f"blunders {self.blunders} must not be negative"),
            (0.0 <= self.measurement_sigma <= 5.0, f"measurement sigma {self.measurement_sigma} px is outside 0..5"),
            (0.0 <= self.error_scale <= 10.0, f"error scale {self.error_scale} is outside 0..10"),
            (1.0 <= self.grid_m <= 20.0, f"ground grid {self.grid_m} m is outside 1..20 m"),
            ((self.centre_lon is None) == (self.centre_lat is None),
             "give both centre_lon and centre_lat, or neither"),
            (len(self.roll_deg) in (0, passes),
             f"{self.configuration} needs {passes} roll angle(s), got {len(self.roll_deg)}"),
            (len(self.dates) in (0, passes), f"{self.configuration} needs {passes} date(s), got {len(self.dates)}"),
            (all(abs(r) <= 27.0 for r in self.roll_deg),
             "roll angles must lie within +-27 degrees (the SPOT mirror range)"),
            (not self.look_table or os.path.isfile(self.look_table),
             f"look-angle table {self.look_table!r} is not a file"),
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
        return dataclasses.replace(self, seed=int(self.seed), dates=tuple(str(d) for d in dates),
                                   roll_deg=tuple(float(r) for r in roll))


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
        raise InputError(f"{config.look_table} is a SPOT {o.mission} scene; {config.configuration} needs a "
                         f"{'SPOT 5' if wanted == 5 else 'SPOT 1-4'} look-angle table")
    return o.psi_x, o.psi_y, o.line_period


def simulate_scene(config, out_dir, feedback=None):
    """Simulate the scene of `config` into the folder `out_dir` (replaced as a whole) and return
    the paths written: {'folder', 'images': {name: {'imagery', 'metadata'}}, 'truth_metadata':
    {name: path}, 'truth', 'dsm', 'dtm', 'classes', 'orthoimage', 'points'}."""
    config = config.resolved()
    step(feedback, 0, f"planning the {config.configuration} acquisition")
    source = jacksboro_dem()
    images, grid, centre = _plan(config, source)
    step(feedback, 5, f"building the terrain ({grid.cols} x {grid.rows} cells of {config.grid_m:g} m)")
    terrain = build_terrain(source, grid, config.seed, config.fractal, config.surface_objects)
    step(feedback, 20, "choosing control/check point candidates")
    candidates, surface = _candidates(config, terrain, images)
    step(feedback, 30, "computing the ground radiance")
    radiance, suns = _radiance(config, terrain, surface, images, candidates, centre)
    rendered, radiometric, footprints = {}, {}, {}
    for k, image in enumerate(images):
        step(feedback, 40 + 45 * k / len(images), f"rendering {image.name} ({image.ncols} x {image.nrows})")
        rendered[image.name], radiometric[image.name] = _render(config, image, surface,
                                                                radiance[image.instrument.pass_index], k)
        footprints[image.name] = _footprint(image, surface)
    step(feedback, 85, "writing the products")
    corrections, trajectory = inject(images, np.random.default_rng([config.seed, 3]), config.error_scale)
    with atomic_dir(out_dir) as tmp:
        paths = _write(tmp, config, images, terrain, rendered, radiance[0], candidates, corrections,
                       trajectory, suns, radiometric, footprints, geodetic_to_ecef(*centre))
    step(feedback, 100)
    return _rebase(paths, tmp, os.path.abspath(os.fspath(out_dir)))


def _plan(config, source):
    """Images over the scene centre (lon, lat, h) and the ground grid covering their footprints
    (heights from the DEM's lowest to its highest plus objects, TERRAIN_MARGIN_M around)."""
    lon_c, lat_c = source.centre if config.centre_lon is None else (config.centre_lon, config.centre_lat)
    lon_min, lat_min, lon_max, lat_max = source.bounds
    if not (lon_min < lon_c < lon_max and lat_min < lat_c < lat_max):
        raise InputError(f"the scene centre ({lon_c:.4f}, {lat_c:.4f}) lies outside the source DEM "
                         f"(lon {lon_min:.4f}..{lon_max:.4f}, lat {lat_min:.4f}..{lat_max:.4f})")
    source_dem = Dem(source.heights + source.geoid, source.geotransform)
    centre = (lon_c, lat_c, source_dem.height(lon_c, lat_c))
    images = plan(config.configuration, centre, config.size_km * 1000.0, config.dates, config.roll_deg,
                  np.random.default_rng([config.seed, 1]), _look_table(config))
    low, high = source_dem.height_range
    bounds = footprint_bounds(images, (low - 10.0, high + OBJECT_MAX_M))
    me, mn = metres_per_degree(lat_c)
    bounds = (bounds[0] - TERRAIN_MARGIN_M / me, bounds[1] - TERRAIN_MARGIN_M / mn,
              bounds[2] + TERRAIN_MARGIN_M / me, bounds[3] + TERRAIN_MARGIN_M / mn)
    check_coverage(source, bounds)
    return images, Grid.covering(bounds, config.grid_m), centre


def _candidates(config, terrain, images):
    """Point candidates (pads levelled under markers first) and the ray-casting surface."""
    rng = np.random.default_rng([config.seed, 2])
    pad = 5.0 * MARKER_SIGMA_M
    clearance = 1.5 * pad + 30.0 if config.markers else CLEARANCE_M
    sites = select_sites(terrain, images, config.points, clearance, rng)
    if config.markers and len(sites):
        level_pads(terrain, sites[:, 0], sites[:, 1], pad)
    surface = Surface(terrain.grid, terrain.dsm)
    heights = Dem(terrain.dtm, terrain.grid.geotransform).height(sites[:, 0], sites[:, 1])
    candidates = image_coordinates(sites, np.atleast_1d(heights), images, surface, config.measurement_sigma,
                                   config.blunders, rng)
    return candidates, surface


def _radiance(config, terrain, surface, images, candidates, centre):
    """Ground radiance of each pass ({pass: array}) and its sun (azimuth, elevation) in degrees."""
    e0, de, n0, dn = terrain.grid.local_metres()
    if config.orthoimage:
        rho = radiometry.load_orthoimage(config.orthoimage, terrain.grid)
    else:
        rho = radiometry.reflectance(terrain.classes, terrain.feature, terrain.dsm - terrain.dtm,
                                     e0, de, n0, dn, config.seed)
    if config.markers:
        radiometry.paint_markers(rho, terrain.grid, candidates.lon, candidates.lat, MARKER_SIGMA_M)
    radiance, suns = {}, {}
    for image in images:
        key = image.instrument.pass_index
        if key not in radiance:
            when = image.epoch + np.timedelta64(int(round(image.centre_time * 1e9)), "ns")
            suns[key] = sun_position(when, centre[0], centre[1])
            light = radiometry.illumination(surface.z, surface.bmax, de, dn, math.radians(suns[key][0]),
                                            math.radians(suns[key][1]), surface.hmax)
            radiance[key] = rho * light
    return radiance, suns


def _render(config, image, surface, radiance, index):
    """DN image of one instrument, with its gain (nominal +-8 %) and offset (+-30 %)."""
    sample = surface.render(*image.line_geometry(), image.look_vectors(), ground_psf_filter(image, surface, radiance))
    if np.isnan(sample).any():
        raise GeometryError(f"{np.isnan(sample).sum()} rays of {image.name} miss the simulated terrain")
    rng = np.random.default_rng([config.seed, 10 + index])
    gain = radiometry.NOMINAL_GAIN * (1.0 + rng.normal(0.0, 0.08))
    offset = radiometry.NOMINAL_OFFSET * (1.0 + rng.normal(0.0, 0.3))
    dn = radiometry.sensor_image(sample, gain, offset, config.noise, config.bits, rng)
    return dn, {"gain": gain, "offset": offset}


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


def ground_psf_filter(image, surface, radiance, pad=64):
    """The ground radiance convolved with the image's PSF projected onto the ground grid, so that
    one ray per pixel sampling it equals the PSF integral of the pixel (radiometry module
    docstring) on locally flat ground. The PSF is separable in (detector, line) with transfer
    function Hc(u) Hr(v), u, v in cycles per detector / line:
      Hc(u) = sinc(u) exp(-2 pi^2 s^2 u^2),  Hr(v) = sinc(n v) sinc(v) exp(-2 pi^2 (s n)^2 v^2)
    (s = OPTICS_SIGMA, n = detector_lines, the line smear box of 1 line); with J the pixel -> grid
    Jacobian (ground_psf_jacobian at the mean DSM height), a ground frequency k (cycles per cell)
    is (u, v) = J^T k, so the filter is exact (analytic, oriented, elongated along track off
    nadir) for the band-limited grid. Relief changes the footprint only through J: a slope or a
    height off the mean rescales it by a few % (second order in the image, see _integrate), J's
    drift across the swath (view angle) likewise. Edges: reflect-padded by `pad` cells."""
    from scipy import fft
    ins = image.instrument
    h = 0.5 * (surface.hmin + surface.hmax)
    jac = ground_psf_jacobian(image, surface.grid, h)
    data = np.pad(np.asarray(radiance, np.float32), pad, mode="reflect")
    shape = [fft.next_fast_len(n, real=True) for n in data.shape]
    ky = fft.fftfreq(shape[0])[:, None]
    kx = fft.rfftfreq(shape[1])[None, :]
    u = jac[0, 0] * kx + jac[1, 0] * ky
    v = jac[0, 1] * kx + jac[1, 1] * ky
    s, n = radiometry.OPTICS_SIGMA, ins.detector_lines
    two_pi2 = 2.0 * math.pi ** 2
    tf = (np.sinc(u) * np.exp(-two_pi2 * s * s * u * u)
          * np.sinc(n * v) * np.sinc(v) * np.exp(-two_pi2 * (s * n) ** 2 * v * v)).astype(np.float32)
    del u, v
    spec = fft.rfft2(data, s=shape, workers=-1)
    spec *= tf
    del tf
    out = fft.irfft2(spec, s=shape, workers=-1)[pad:pad + radiance.shape[0], pad:pad + radiance.shape[1]]
    return np.ascontiguousarray(out, dtype=radiance.dtype)


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
    out = np.zeros(a.shape[:axis] + (n,) + a.shape[axis + 1:])
    for m, wm in enumerate(w):
        out += wm * (a[:, m:m + n] if axis == 1 else a[m:m + n])
    return out


def _footprint(image, surface):
    """Ground points of the rays of the corner and centre pixel centres."""
    cols = np.array([0.5, image.ncols - 0.5, image.ncols - 0.5, 0.5, 0.5 * image.ncols])
    rows = np.array([0.5, 0.5, image.nrows - 0.5, image.nrows - 0.5, image.centre_row])
    pos, mat = image.line_geometry(rows)
    ground = surface.trace(pos, mat, image.look_vectors(cols))
    return [{"col": c, "row": r, "lon": g[0], "lat": g[1], "h": g[2]} for c, r, g in zip(cols, rows, ground)]


def _write(folder, config, images, terrain, rendered, radiance, candidates, corrections, trajectory,
           suns, radiometric, footprints, centre):
    join = os.path.join
    paths = {"folder": folder, "images": {}, "truth_metadata": {}}
    for image in images:
        sun = suns[image.instrument.pass_index]
        product = join(folder, image.name)
        os.makedirs(product)
        outputs.write_imagery(join(product, "IMAGERY.TIF"), rendered[image.name])
        write_dimap(join(product, "METADATA.DIM"), image.orientation(corrections[image.name]), sun=sun,
                    nbits=config.bits)
        truth_dir = join(folder, "truth", image.name)
        os.makedirs(truth_dir)
        write_dimap(join(truth_dir, "METADATA.DIM"), image.orientation(), sun=sun, nbits=config.bits)
        paths["images"][image.name] = {"imagery": join(product, "IMAGERY.TIF"),
                                       "metadata": join(product, "METADATA.DIM")}
        paths["truth_metadata"][image.name] = join(truth_dir, "METADATA.DIM")
    grid = terrain.grid
    heights = {"HEIGHTS": "ellipsoidal, WGS 84 (EPSG:4979), metres"}
    for name, array, description in (("dsm", terrain.dsm, "DSM"), ("dtm", terrain.dtm, "DTM")):
        paths[name] = join(folder, f"{name}.tif")
        outputs.write_raster(paths[name], array.astype(np.float32), grid, description=description, metadata=heights)
    paths["classes"] = join(folder, "classes.tif")
    outputs.write_raster(paths["classes"], terrain.classes, grid, nodata=0, description="land cover",
                         metadata={f"CLASS_{k}": v for k, v in CLASSES.items() if k})
    paths["orthoimage"] = join(folder, "orthoimage.tif")
    outputs.write_raster(paths["orthoimage"], radiometry.orthoimage(radiance), grid, description="ground radiance")
    paths["points"] = join(folder, "points.csv")
    outputs.write_points(paths["points"], candidates)
    paths["truth"] = join(folder, "truth", "truth.json")
    outputs.write_json(paths["truth"], _truth(config, images, corrections, trajectory, suns, radiometric, footprints,
                                              terrain, centre))
    return paths


def _truth(config, images, corrections, trajectory, suns, radiometric, footprints, terrain, centre):
    config_dict = dataclasses.asdict(config)
    per_image = {}
    for image in images:
        c = corrections[image.name]
        per_image[image.name] = {
            "mission": image.instrument.mission, "instrument": image.instrument.instrument,
            "instrument_index": image.instrument.instrument_index, "pass": image.instrument.pass_index,
            "size": [image.ncols, image.nrows], "epoch": str(image.epoch), "centre_time": image.centre_time,
            "centre_row": image.centre_row, "line_period": image.instrument.line_period,
            "sun_azimuth_elevation": suns[image.instrument.pass_index],
            "corrections": {"position": c.position, "attitude": c.attitude, "look": c.look,
                            "time_scale": c.time_scale},
            "radiometry": radiometric[image.name], "footprint": footprints[image.name],
        }
    return {
        "config": config_dict,
        "images": per_image,
        "trajectory_errors": trajectory,
        "base_to_height": _base_to_height(images, centre),
        "classes": {str(k): v for k, v in CLASSES.items()},
        "towns": terrain.towns,
        "forest_fraction": float(np.mean(terrain.classes == FOREST)),
        "grid": {"geotransform": terrain.grid.geotransform, "size": [terrain.grid.cols, terrain.grid.rows],
                 "crs": "EPSG:4326, heights ellipsoidal (WGS 84)"},
        "conventions": "image (col, row): GDAL, (0, 0) top-left corner of the first pixel; truth = supplied "
                       "+ corrections (spot_orientation.Corrections, tau about each image's centre_time); "
                       "look[0] psi_x, look[1] psi_y",
    }


def _base_to_height(images, centre):
    """B/H of every image pair: |P_i - P_j| over the mean radial height |P| - |G| of the
    satellites above the scene centre G, P at the time each image sees G."""
    out = {}
    for i, a in enumerate(images):
        for b in images[i + 1:]:
            pa, _ = a.orbit.state(a.centre_time)
            pb, _ = b.orbit.state(b.centre_time)
            height = 0.5 * (np.linalg.norm(pa) + np.linalg.norm(pb)) - np.linalg.norm(centre)
            out[f"{a.name}-{b.name}"] = float(np.linalg.norm(pa - pb) / height)
    return out


def _rebase(value, old, new):
    """`value` with the temporary folder prefix `old` replaced by `new`."""
    if isinstance(value, dict):
        return {k: _rebase(v, old, new) for k, v in value.items()}
    return new + value[len(old):] if isinstance(value, str) and value.startswith(old) else value
