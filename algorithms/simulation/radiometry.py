"""Ground radiance and image formation.

Ground: Lambertian reflectance rho per land-cover class with procedural texture (water and
uniform grass parcels are nearly textureless, so matching there should fail), lit by the sun:

    L = rho (E_dir cos(i) lit + E_sky (1 + n_z) / 2),   E_dir = 0.85, E_sky = 0.15,

with i the incidence angle on the DSM normal n, `lit` 0 in cast shadows (ray towards the sun
blocked by the DSM, see render.first_hit) and (1 + n_z)/2 the visible sky fraction. A user
orthoimage replaces rho.

Sensor: each pixel integrates L over its point spread function *before* sampling (image
formation is a convolution of the ground radiance followed by sampling; blurring an already
point-sampled image cannot undo aliasing). The PSF is separable in (detector, line):
  across track  box(1 detector) x Gaussian optics of OPTICS_SIGMA detectors;
  along track   box(detector_lines) x box(1 line: motion during the integration time)
                x Gaussian optics of OPTICS_SIGMA * detector_lines lines,
so MTF(Nyquist) = sinc(1/2) exp(-pi^2 0.4^2 / 2) = 0.29 across (typical of SPOT), 0.18 along
(the smear) and ~0 along for HRS, whose 10 m detectors are sampled every 5 m. The renderer
applies it on the ground: the radiance grid is convolved once per image with the PSF projected
onto it (scene.ground_psf_filter, FFT, exact on flat ground) and one ray per pixel samples that;
scene._integrate, a quadrature on `SUPERSAMPLE` x `SUPERSAMPLE` rays per pixel (`psf_kernel`),
is the slow reference. Why it matters: point sampling a 10 m HRS pixel from 5 m ground texture folds
everything between 1/20 and 1/10 cycles/m back into the image, differently in each image, a
deterministic misfit of the matcher (docs/validation.md#simulator-psf).
Then DN = gain L + offset (path radiance; gain and offset differ between sensors), additive Gaussian
noise, rounding to `bits` (DN 0 is kept for nodata, as in DIMAP). The true orthoimage product is
the ground radiance L with the nominal gain and offset."""

import math

import numpy as np
from numba import njit, prange

from ..errors import InputError
from .noise import fbm, uniform
from .render import BLOCK, first_hit
from .terrain import BARE, CITY, CROPS, FOREST, WATER, gradient_en

E_DIRECT = 0.85
E_SKY = 0.15
NOMINAL_GAIN = 450.0  # DN (8 bit) per unit radiance
NOMINAL_OFFSET = 12.0  # DN (8 bit) of path radiance
OPTICS_SIGMA = 0.4  # detectors: Gaussian optics PSF (with the detector box, MTF(Nyquist) 0.29)
SUPERSAMPLE = 3  # quadrature rays per pixel and axis for the PSF integral (odd)


def psf_kernel(width, smear, sigma, k):
    """Quadrature weights at offsets m / k, m = -M..M (pixels), of box(width) x box(smear) x
    Gaussian(sigma): the continuous PSF averaged over each 1/k sub-interval, summing to 1."""
    fine = 32
    d = 1.0 / (k * fine)
    half = 0.5 * (width + smear) + 4.0 * sigma + 1.0 / k
    u = np.arange(-np.ceil(half / d), np.ceil(half / d) + 1) * d
    psf = np.exp(-0.5 * (u / sigma) ** 2)
    for w in (width, smear):
        if w > 0:
            n = 2 * int(round(0.5 * w / d)) + 1  # odd: centred
            psf = np.convolve(psf, np.ones(n) / n, mode="same")
    m_max = int(np.ceil(half * k))
    out = np.array([psf[np.abs(u - m / k) <= 0.5 / k + 1e-12].sum() for m in range(-m_max, m_max + 1)])
    out /= out.sum()
    keep = np.flatnonzero(out > 1e-6 * out.max())
    r = max(m_max - keep[0], keep[-1] - m_max)
    out = out[m_max - r : m_max + r + 1]
    return out / out.sum()


@njit(cache=True, nogil=True, parallel=True)
def reflectance(classes, feature, objects, e0, de, n0, dn, seed):
    """Reflectance rho per cell from its class, feature id and object height (module docstring)."""
    rows, cols = classes.shape
    out = np.empty((rows, cols), np.float32)
    for i in prange(rows):
        n = n0 - i * dn
        for j in range(cols):
            e = e0 + j * de
            c = classes[i, j]
            f = feature[i, j]
            if c == WATER:
                r = 0.035 + 0.004 * fbm(e / 40.0, n / 40.0, seed + 1, 2, 0.5)
            elif c == BARE:
                theta = math.pi * uniform(f, 0, seed + 2)
                period = 6.0 + 9.0 * uniform(f, 1, seed + 2)
                furrow = math.sin(2 * math.pi * (e * math.cos(theta) + n * math.sin(theta)) / period)
                r = (
                    0.20
                    + 0.15 * uniform(f, 2, seed + 2)
                    + 0.035 * fbm(e / 12.0, n / 12.0, seed + 3, 3, 0.5)
                    + 0.015 * furrow
                )
            elif c == CROPS:
                theta = math.pi * uniform(f, 0, seed + 4)
                period = 8.0 + 12.0 * uniform(f, 1, seed + 4)
                rows_amp = 0.025 * max(0.0, 2.0 * uniform(f, 3, seed + 4) - 1.0)
                stripe = math.sin(2 * math.pi * (e * math.cos(theta) + n * math.sin(theta)) / period)
                r = (
                    0.07
                    + 0.10 * uniform(f, 2, seed + 4)
                    + rows_amp * stripe
                    + 0.008 * fbm(e / 15.0, n / 15.0, seed + 5, 2, 0.5)
                )
            elif c == FOREST:
                r = (
                    0.035
                    + 0.0015 * objects[i, j]
                    + 0.015 * uniform(f, 0, seed + 6)
                    + 0.012 * fbm(e / 10.0, n / 10.0, seed + 7, 2, 0.5)
                )
            elif c == CITY:
                if f == 0:
                    r = 0.10 + 0.01 * fbm(e / 8.0, n / 8.0, seed + 8, 2, 0.5)
                elif f == 1:
                    r = 0.13 + 0.04 * fbm(e / 15.0, n / 15.0, seed + 9, 2, 0.5)
                else:
                    r = 0.15 + 0.30 * uniform(f, 0, seed + 10) + 0.01 * fbm(e / 6.0, n / 6.0, seed + 11, 1, 0.5)
            else:
                r = 0.0
            out[i, j] = max(r, 0.005)
    return out


@njit(cache=True, nogil=True, parallel=True)
def illumination(z, bmax, de, dn, sun_az, sun_el, hmax, i0, i1, j0, j1):
    """E_dir cos(i) lit + E_sky (1 + n_z)/2 per vertex (i0..i1, j0..j1) of the DSM z (cells de x dn
    metres, rows southwards); `lit` from a ray towards the sun, started 5 cm above the surface, that
    climbs to `hmax` (the highest DSM height, of the whole grid where z is a window: the window must
    reach that far towards the sun, see sun_margins)."""
    se, sn, su = math.sin(sun_az) * math.cos(sun_el), math.cos(sun_az) * math.cos(sun_el), math.sin(sun_el)
    gx, gy = math.sin(sun_az) / de, -math.cos(sun_az) / dn  # grid cells per metre towards the sun
    slope = math.tan(sun_el)
    out = np.empty((i1 - i0, j1 - j0), np.float32)
    for i in prange(i0, i1):
        for j in range(j0, j1):
            dzde, dzdn = gradient_en(z, i, j, de, dn)
            norm = math.sqrt(dzde * dzde + dzdn * dzdn + 1.0)
            cos_i = (-dzde * se - dzdn * sn + su) / norm
            sky = 0.5 * (1.0 + 1.0 / norm)
            lit = 0.0
            if cos_i > 0.0:
                z0 = z[i, j] + 0.05
                length = (hmax - z0) / slope + 1.0
                s = first_hit(
                    float(j), float(i), z0, j + gx * length, i + gy * length, z0 + slope * length, z, bmax, BLOCK
                )
                lit = 1.0 if s < 0.0 else 0.0
            out[i - i0, j - j0] = E_DIRECT * max(cos_i, 0.0) * lit + E_SKY * sky
    return out


def sun_margins(de, dn, sun_az, sun_el, relief):
    """(top, bottom, left, right) cells a window needs around a tile for `illumination`: the reach of
    a shadow ray over `relief` metres, on the sun's side (1 cell elsewhere, for the gradient)."""
    reach = relief / math.tan(sun_el) + 1.0
    rows = int(math.ceil(reach * abs(math.cos(sun_az)) / dn)) + 2
    cols = int(math.ceil(reach * abs(math.sin(sun_az)) / de)) + 2
    north, east = math.cos(sun_az) > 0.0, math.sin(sun_az) > 0.0
    return rows if north else 1, 1 if north else rows, 1 if east else cols, cols if east else 1


def paint_markers(rho, grid, lon, lat, sigma_m, pad=0.03, peak=0.85, origin=(0, 0)):
    """Bright targets: rho = pad + peak exp(-d^2 / 2 sigma^2) within 5 sigma of each (lon, lat)
    (d in metres), a Gaussian spot on a round dark pad. `rho` holds the cells of `grid` from row and
    column `origin` on (a tile)."""
    de, dn = grid.cell_metres
    radius = 5.0 * sigma_m
    x, y = grid.vertex(np.atleast_1d(lon), np.atleast_1d(lat))
    x, y = x - origin[1], y - origin[0]
    rows, cols = rho.shape
    ri, rj = int(math.ceil(radius / dn)), int(math.ceil(radius / de))
    for xc, yc in zip(x, y):
        i, j = int(math.floor(yc)), int(math.floor(xc))
        i0, i1, j0, j1 = max(i - ri, 0), min(i + ri + 2, rows), max(j - rj, 0), min(j + rj + 2, cols)
        if i1 <= i0 or j1 <= j0:
            continue  # off this tile
        ii, jj = np.mgrid[i0:i1, j0:j1]
        d2 = ((jj - xc) * de) ** 2 + ((ii - yc) * dn) ** 2
        inside = d2 <= radius * radius
        rho[ii[inside], jj[inside]] = pad + peak * np.exp(-0.5 * d2[inside] / sigma_m**2)


def sensor_image(radiance, gain, offset, noise, bits, rng):
    """DN image (uint8 / uint16) from the PSF-integrated radiance (module docstring). `noise` is
    the noise standard deviation in 8-bit DN; gain and offset are in 8-bit DN and scaled to `bits`."""
    missing = ~np.isfinite(radiance)
    filled = np.where(missing, 0.0, radiance).astype(np.float64)
    scale = 2.0 ** (bits - 8)
    dn = scale * (gain * filled + offset)
    if noise > 0:
        dn += rng.normal(0.0, noise * scale, dn.shape)
    out = np.clip(np.rint(dn), 1, 2**bits - 1).astype(np.uint8 if bits == 8 else np.uint16)
    out[missing] = 0
    return out


def orthoimage(radiance):
    """8-bit true orthoimage of the ground radiance with the nominal gain and offset."""
    return np.clip(np.rint(NOMINAL_GAIN * radiance + NOMINAL_OFFSET), 1, 255).astype(np.uint8)


class OrthoimageReflectance:
    """Reflectance from a user orthoimage (any CRS GDAL reads), tile by tile: band 1 warped
    bilinearly onto the grid's window, its 1st..99th percentiles over the scene's ground (sampled
    on a warp of at most PERCENTILE_SIDE cells a side) mapped linearly to reflectance 0.03..0.45."""

    PERCENTILE_SIDE = 1024

    def __init__(self, path, grid):
        from osgeo import gdal

        gdal.UseExceptions()
        self.path, self.grid = str(path), grid
        try:
            self.src = gdal.Open(self.path)
        except RuntimeError as exc:
            raise InputError(f"cannot read the orthoimage {self.path}: {exc}") from exc
        scale = max(1, math.ceil(max(grid.rows, grid.cols) / self.PERCENTILE_SIDE))
        coarse = self._warp(grid.bounds, math.ceil(grid.cols / scale), math.ceil(grid.rows / scale))
        self.low, self.high = np.percentile(coarse, [1, 99])
        if not self.high > self.low:
            raise InputError(f"the orthoimage {path} is constant over the scene; it has no texture to image")

    def _warp(self, bounds, width, height):
        from osgeo import gdal

        try:
            warped = gdal.Warp(
                "",
                self.src,
                format="MEM",
                dstSRS="EPSG:4326",
                outputBounds=bounds,
                width=width,
                height=height,
                resampleAlg="bilinear",
                outputType=gdal.GDT_Float32,
                dstNodata=float("nan"),
            )
        except RuntimeError as exc:
            raise InputError(f"cannot read the orthoimage {self.path}: {exc}") from exc
        values = warped.GetRasterBand(1).ReadAsArray().astype(np.float32)
        if not np.all(np.isfinite(values)):
            raise InputError(
                f"the orthoimage {self.path} does not cover the scene's ground "
                f"(lon/lat {', '.join(f'{b:.4f}' for b in self.grid.bounds)}); give one that does"
            )
        return values

    def __call__(self, window):
        """Reflectance of the cells (i0, i1, j0, j1)."""
        i0, i1, j0, j1 = window
        values = self._warp(self.grid.window(*window).bounds, j1 - j0, i1 - i0)
        return (0.03 + 0.42 * np.clip((values - self.low) / (self.high - self.low), 0.0, 1.0)).astype(np.float32)
