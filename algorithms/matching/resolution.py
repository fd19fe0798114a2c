"""Resolution adaptation of an image pair (Kornus et al. 2006, section 3.3: "image scales adapted by
scale factors"): the finer image is low-passed to the coarser one's footprint, so that a template
sees the same ground detail in both images. Used by both matchers, the MPGC refinement and the
measurement window's transfers.

Each image's point spread function (PSF) is a Gaussian-equivalent covariance in its own pixels: from
the instrument (SENSOR_PSF: detector box, detector lines, motion smear, optics) or, where the
instrument is unknown (RPC), a Gaussian of GrowParams.psf_sigma detectors with square detectors on
the ground. The models' local affine carries one image's PSF into the other's pixels; each image gets
the positive part of the difference."""

import math

import numpy as np

from .imagery import Smoothed, as_image
from .pair_geometry import local_affine
from .params import GrowParams


def _psf_aspect(model, cols, rows, h):
    """Along-track PSF size over the across-track one, in lines per detector: ground size of a
    detector over that of a line, at least 1. A pushbroom's detectors are square on the ground, so
    an image sampled finer along track than across (SPOT 5 HRS: 10 m detectors, 5 m lines) has a
    PSF that many lines long; 1 where the models cannot tell."""
    try:
        lon, lat = (
            np.asarray(v, float)
            for v in model.image_to_ground(
                np.array([cols, cols + 1.0, cols]), np.array([rows, rows, rows + 1.0]), np.full(3, h)
            )[:2]
        )
    except Exception:
        return 1.0
    c = math.cos(math.radians(float(lat[0])))
    across = math.hypot((lon[1] - lon[0]) * c, lat[1] - lat[0])
    along = math.hypot((lon[2] - lon[0]) * c, lat[2] - lat[0])
    return max(1.0, across / along) if along > 0 and np.isfinite(across / along) else 1.0


#: PSF of the SPOT instruments, keyed by INSTRUMENT (SENSOR_CODE-specific entries first):
#: (detector width across, in detectors = columns; detector_lines: along-track detector size in
#: lines; motion smear during the integration time, lines; Gaussian optics sigma, detectors).
#: HRS: 10 m detectors sampled every 5 m along track. HRG 'T' (THR, 2.5 m from two staggered
#: 5 m arrays, resampled) is not a plain pushbroom PSF and stays unknown.
SENSOR_PSF = {
    ("HRS", None): (1.0, 2.0, 1.0, 0.4),
    ("HRG", "T"): None,
    ("HRG", None): (1.0, 1.0, 1.0, 0.4),
    ("HRV", None): (1.0, 1.0, 1.0, 0.4),
    ("HIR", None): (1.0, 1.0, 1.0, 0.4),
}


def sensor_psf(model):
    """Gaussian-equivalent PSF covariance of an image in its own px, diag(across = columns, along
    = lines), from SENSOR_PSF: a box of width w has variance w^2 / 12, the smear likewise, the
    optics sigma^2 (in lines: sigma * detector_lines). None where the model does not tell its
    instrument (RPC) or the instrument is not listed."""
    o = getattr(model, "orientation", None)
    instrument = str(getattr(o, "instrument", "") or "").upper()
    code = str(getattr(o, "sensor_code", "") or "").upper()
    key = (instrument, code) if (instrument, code) in SENSOR_PSF else (instrument, None)
    desc = SENSOR_PSF.get(key)
    if desc is None:
        return None
    width, lines, smear, sigma = desc
    across = width**2 / 12.0 + sigma**2
    along = lines**2 / 12.0 + smear**2 / 12.0 + (sigma * lines) ** 2
    return np.diag([across, along])


def _pixel_psf(model, cols, rows, h, s):
    """psf "pixel": Gaussian of s detectors, s^2 diag(1, q^2) in own px (q = _psf_aspect)."""
    return s * s * np.diag([1.0, _psf_aspect(model, cols, rows, h) ** 2])


def adapt_resolution(image1, image2, model1, model2, params, hr):
    """(image1, image2) with the finer image low-passed to the coarser one's footprint (Kornus et al.
    2006, 3.3: scale factors; GrowParams.psf / psf_sigma). Each image's PSF is a Gaussian-equivalent
    covariance P in its own px: psf "sensor" takes it from the instrument (sensor_psf: detector
    box, detector lines, motion smear, optics as variances), for both images or, if either is
    unknown (RPC), neither; psf "pixel" (and the fallback) uses s^2 diag(1, q^2) with s =
    psf_sigma and q = _psf_aspect (square detectors; q = 2 for SPOT 5 HRS, whose lines are half a
    detector). With A the models' local affine (image 1 -> image 2 px) at the centre of image 1,
    image 2's PSF seen in image-1 px is A^-1 P2 A^-T, so image 1 gets the extra A^-1 P2 A^-T - P1
    and image 2 likewise A P1 A^T - P2 (difference of variances), each clipped to its positive
    part; the filter is separable (the diagonal: pushbroom pairs are near axis-aligned). Sigmas
    under 0.1 px are left out (same-resolution pairs stay untouched)."""
    mode = params.psf
    s = float(params.psf_sigma)
    if mode == "off":
        return image1, image2
    cols, rows = image1.size
    c2, r2 = image2.size
    h = 0.5 * (hr[0] + hr[1])
    p1 = p2 = None
    if mode == "sensor":
        p1, p2 = sensor_psf(model1), sensor_psf(model2)
    if p1 is None or p2 is None:
        if s <= 0.0:
            return image1, image2
        p1 = _pixel_psf(model1, 0.5 * cols, 0.5 * rows, h, s)
        p2 = _pixel_psf(model2, 0.5 * c2, 0.5 * r2, h, s)
    _, _, *aff = local_affine(model1, model2, 0.5 * cols, 0.5 * rows, h)
    a = np.array([float(v[0]) for v in aff]).reshape(2, 2)
    if not np.all(np.isfinite(a)) or abs(np.linalg.det(a)) < 1e-6:
        return image1, image2
    inv = np.linalg.inv(a)
    out = []
    for image, extra in ((image1, inv @ p2 @ inv.T - p1), (image2, a @ p1 @ a.T - p2)):
        w, v = np.linalg.eigh(extra)
        sx, sy = np.sqrt(np.diag((v * np.maximum(w, 0.0)) @ v.T))
        out.append(Smoothed(image, sx, sy) if max(sx, sy) >= 0.1 else image)
    return out[0], out[1]


def adapted_images(images, models, hr, grow=None):
    """The images, the finer of each reference-search pair low-passed to the coarser one's
    resolution (adapt_resolution with `grow`'s PSF settings, default GrowParams();
    Image-like, read by windows)."""
    grow = grow or GrowParams()
    ref, s1 = adapt_resolution(as_image(images[0]), as_image(images[1]), models[0], models[1], grow, hr)
    adapted = [ref, s1]
    if len(images) == 3:
        adapted.append(adapt_resolution(as_image(images[0]), as_image(images[2]), models[0], models[2], grow, hr)[1])
    return adapted
