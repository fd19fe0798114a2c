"""The RPC00B rational polynomial sensor model (RPC, RFM) of Pleiades, IKONOS, WorldView, ...

With ground coordinates normalised as

    L = (lon - LONG_OFF) / LONG_SCALE,  P = (lat - LAT_OFF) / LAT_SCALE,  H = (h - HEIGHT_OFF) / HEIGHT_SCALE

the normalised image coordinates are ratios of 20-term cubic polynomials, s = SAMP_NUM / SAMP_DEN,
l = LINE_NUM / LINE_DEN of (L, P, H), with the terms in the RPC00B order (NITF STDI-0002, GDAL's
RPCComputeTerms): 1 L P H LP LH PH L^2 P^2 H^2 PLH L^3 LP^2 LH^2 L^2P P^3 PH^2 L^2H P^2H H^3.
RPC00B puts the centre of the first pixel at (0, 0); this model works in GDAL's convention (the first
pixel's top-left corner is (0, 0)) on the raster actually opened, a crop whose top-left corner lies at
(col0, row0) of the image the RPC describes:

    col = SAMP_OFF + s SAMP_SCALE + 0.5 - col0,   row = LINE_OFF + l LINE_SCALE + 0.5 - row0

(the + 0.5 is what GDAL's RPC transformer adds too). The conversion happens once, when the model is
built; the readers and writers are in rpc_io.py.

An adjusted model carries an image-space affine bias correction (the block adjustment's RPC bias
compensation, Grodecki and Dial 2003): with u = (col - c_c) / 1000, v = (row - r_c) / 1000 about the
raster centre (c_c, r_c) = size / 2,

    col' = col + A0 + A1 u + A2 v,   row' = row + B0 + B1 u + B2 v,   bias = (A0, A1, A2, B0, B1, B2).

RPC files cannot hold it: an adjusted model is exported by fitting new RPCs to it (rpc_fit.py).

Validity domain: the normalised cube L, P, H in [-1, 1]. Every RPC is checked when it is read
(RpcCoefficients.from_fields, which all readers and the model file pass through) on a grid of
DOMAIN_NODES^3 points of that cube: both denominators must keep one sign (no pole inside the domain)
and the image coordinates must be finite. A pole between two grid points closer than the grid step is
not seen.

Before that, the values must describe an image of a place on Earth (`_check_geometry`), so that a damaged or
mistyped RPC is refused where it is read, naming its fault, instead of failing later as a singular
iteration: positive scales; LAT_OFF a latitude and LONG_OFF a longitude; numerators that are not all zero; image
coordinates that change along two ground directions at the ground centre (LONG_OFF, LAT_OFF, HEIGHT_OFF). The
ground centre need not project into the image: the RPC of a crop keeps the ground domain of its scene and
shifts only the image offsets (the Pleiades triplet of the tests projects its centre thousands of pixels away).
An RPC read from a file must also describe, at that centre,
a pixel whose ground footprint (metres, from the rational functions' derivatives) is at most
MAX_PIXEL_ELONGATION times longer than wide (`_check_geometry` with `pixel_shape`): sensors look at the ground with
near-square pixels (SPOT 5 HRS: 10 x 5 m), while LAT_OFF and LONG_OFF swapped move the image to another
latitude, where the same degrees of longitude span other metres."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..errors import GeometryError, MetadataError
from ..geodesy import flat_points, metres_per_degree
from . import rpc_io
from .base import Coordinate, SensorModel, shaped_points
from .rpc_io import COEFF_KEYS, OFFSET_KEYS, SCALE_KEYS

NUM_TERMS = 20
#: grid points per axis of the validity-domain check (module docstring): steps of 0.1 in L, P, H
DOMAIN_NODES = 21
#: the longest over the shortest side of a pixel's ground footprint an RPC may describe (module docstring)
MAX_PIXEL_ELONGATION = 5.0

#: image_to_ground stops when the image residual is below PX_TOL pixels and the last Newton step
#: below DEG_TOL degrees
PX_TOL = 1e-8
DEG_TOL = 1e-10
MAX_ITER = 50


def rpc_terms(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """(n, 20) RPC00B terms of normalised x = L, y = P, z = H (arrays), in `_poly`'s order: the design
    matrix of the cubic, so that rpc_terms(x, y, z) @ c == _poly(c, x, y, z)."""
    return np.column_stack(
        [
            np.ones_like(x),
            x,
            y,
            z,
            x * y,
            x * z,
            y * z,
            x * x,
            y * y,
            z * z,
            x * y * z,
            x**3,
            x * y * y,
            x * z * z,
            x * x * y,
            y**3,
            y * z * z,
            x * x * z,
            y * y * z,
            z**3,
        ]
    )


def domain_grid() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(L, P, H) of the DOMAIN_NODES^3 grid points of the validity domain [-1, 1]^3, flat arrays, the
    centre (0, 0, 0) among them."""
    axis = np.linspace(-1.0, 1.0, DOMAIN_NODES)
    x, y, z = np.meshgrid(axis, axis, axis, indexing="ij")
    return x.ravel(), y.ravel(), z.ravel()


def keeps_sign(values: np.ndarray) -> bool:
    """Whether a denominator's values are all finite and all > 0 or all < 0 (no pole among them)."""
    return bool(np.all(np.isfinite(values)) and (np.all(values > 0.0) or np.all(values < 0.0)))


# ---------------------------------------------------------------------------------------------
# numba kernels
# ---------------------------------------------------------------------------------------------


@njit(cache=True, nogil=True)
def _poly(c: np.ndarray, x: float, y: float, z: float) -> float:
    """RPC00B cubic with x = L (longitude), y = P (latitude), z = H (height), all normalised."""
    return (
        c[0]
        + c[1] * x
        + c[2] * y
        + c[3] * z
        + c[4] * x * y
        + c[5] * x * z
        + c[6] * y * z
        + c[7] * x * x
        + c[8] * y * y
        + c[9] * z * z
        + c[10] * x * y * z
        + c[11] * x * x * x
        + c[12] * x * y * y
        + c[13] * x * z * z
        + c[14] * x * x * y
        + c[15] * y * y * y
        + c[16] * y * z * z
        + c[17] * x * x * z
        + c[18] * y * y * z
        + c[19] * z * z * z
    )


@njit(cache=True, nogil=True)
def _poly_grad(c: np.ndarray, x: float, y: float, z: float) -> tuple[float, float, float]:
    """(d/dx, d/dy, d/dz) of `_poly`."""
    dx = (
        c[1]
        + c[4] * y
        + c[5] * z
        + 2.0 * c[7] * x
        + c[10] * y * z
        + 3.0 * c[11] * x * x
        + c[12] * y * y
        + c[13] * z * z
        + 2.0 * c[14] * x * y
        + 2.0 * c[17] * x * z
    )
    dy = (
        c[2]
        + c[4] * x
        + c[6] * z
        + 2.0 * c[8] * y
        + c[10] * x * z
        + 2.0 * c[12] * x * y
        + c[14] * x * x
        + 3.0 * c[15] * y * y
        + c[16] * z * z
        + 2.0 * c[18] * y * z
    )
    dz = (
        c[3]
        + c[5] * x
        + c[6] * y
        + 2.0 * c[9] * z
        + c[10] * x * y
        + 2.0 * c[13] * x * z
        + 2.0 * c[16] * y * z
        + c[17] * x * x
        + c[18] * y * y
        + 3.0 * c[19] * z * z
    )
    return dx, dy, dz


@njit(cache=True, nogil=True)
def _rational_grad(num: np.ndarray, den: np.ndarray, x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """q = num / den and its gradient by the quotient rule: dq = (dnum - q dden) / den."""
    d = _poly(den, x, y, z)
    q = _poly(num, x, y, z) / d
    nx, ny, nz = _poly_grad(num, x, y, z)
    dx, dy, dz = _poly_grad(den, x, y, z)
    return q, (nx - q * dx) / d, (ny - q * dy) / d, (nz - q * dz) / d


@njit(cache=True, nogil=True)
def _ground_to_image_kernel(
    lon: np.ndarray,
    lat: np.ndarray,
    h: np.ndarray,
    coef: np.ndarray,
    nrm: np.ndarray,
    col: np.ndarray,
    row: np.ndarray,
) -> None:
    """col, row of (lon, lat, h); coef rows: LINE_NUM, LINE_DEN, SAMP_NUM, SAMP_DEN; nrm: see
    RpcModel._nrm."""
    for i in range(lon.size):
        x = (lon[i] - nrm[0]) / nrm[1]
        y = (lat[i] - nrm[2]) / nrm[3]
        z = (h[i] - nrm[4]) / nrm[5]
        col[i] = _poly(coef[2], x, y, z) / _poly(coef[3], x, y, z) * nrm[7] + nrm[6]
        row[i] = _poly(coef[0], x, y, z) / _poly(coef[1], x, y, z) * nrm[9] + nrm[8]


@njit(cache=True, nogil=True)
def _partials_kernel(
    lon: np.ndarray, lat: np.ndarray, h: np.ndarray, coef: np.ndarray, nrm: np.ndarray, out: np.ndarray
) -> None:
    """out[i] = d(col, row) / d(lon, lat, h) as a 2 x 3 matrix (px/deg, px/deg, px/m)."""
    for i in range(lon.size):
        x = (lon[i] - nrm[0]) / nrm[1]
        y = (lat[i] - nrm[2]) / nrm[3]
        z = (h[i] - nrm[4]) / nrm[5]
        _, sx, sy, sz = _rational_grad(coef[2], coef[3], x, y, z)
        _, lx, ly, lz = _rational_grad(coef[0], coef[1], x, y, z)
        out[i, 0, 0] = sx * nrm[7] / nrm[1]
        out[i, 0, 1] = sy * nrm[7] / nrm[3]
        out[i, 0, 2] = sz * nrm[7] / nrm[5]
        out[i, 1, 0] = lx * nrm[9] / nrm[1]
        out[i, 1, 1] = ly * nrm[9] / nrm[3]
        out[i, 1, 2] = lz * nrm[9] / nrm[5]


@njit(cache=True, nogil=True)
def _residual(
    coef: np.ndarray, nrm: np.ndarray, x: float, y: float, z: float, s_goal: float, l_goal: float
) -> tuple[float, float, float, float, float, float]:
    """Image residual (pixels) of normalised ground (x, y, z) and its Jacobian in normalised units."""
    s, sx, sy, _ = _rational_grad(coef[2], coef[3], x, y, z)
    ln, lx, ly, _ = _rational_grad(coef[0], coef[1], x, y, z)
    return (s - s_goal) * nrm[7], (ln - l_goal) * nrm[9], sx * nrm[7], sy * nrm[7], lx * nrm[9], ly * nrm[9]


@njit(cache=True, nogil=True)
def _image_to_ground_one(
    coef: np.ndarray,
    nrm: np.ndarray,
    col: float,
    row: float,
    h: float,
    px_tol: float,
    deg_tol: float,
    max_iter: int,
) -> tuple[float, float, int]:
    """Newton's method with step halving on (L, P) for fixed H, started at the ground offsets.

    Returns (lon, lat, status): status 0 converged, 1 not converged, 2 singular or non-finite."""
    s_goal = (col - nrm[6]) / nrm[7]
    l_goal = (row - nrm[8]) / nrm[9]
    z = (h - nrm[4]) / nrm[5]
    x = 0.0
    y = 0.0
    fs, fl, a, b, c, d = _residual(coef, nrm, x, y, z, s_goal, l_goal)
    r2 = fs * fs + fl * fl
    step = math.inf
    for _ in range(max_iter):
        if not math.isfinite(r2):
            return math.nan, math.nan, 2
        if abs(fs) < px_tol and abs(fl) < px_tol and step < deg_tol:
            return x * nrm[1] + nrm[0], y * nrm[3] + nrm[2], 0
        det = a * d - b * c
        if det == 0.0 or not math.isfinite(det):
            return math.nan, math.nan, 2
        dx = (b * fl - d * fs) / det
        dy = (c * fs - a * fl) / det
        t = 1.0
        while True:
            fs, fl, a, b, c, d = _residual(coef, nrm, x + t * dx, y + t * dy, z, s_goal, l_goal)
            r2_new = fs * fs + fl * fl
            if r2_new <= r2 or t < 1e-6:
                break
            t *= 0.5
        x += t * dx
        y += t * dy
        r2 = r2_new
        step = t * max(abs(dx) * abs(nrm[1]), abs(dy) * abs(nrm[3]))
    return math.nan, math.nan, 1


@njit(cache=True, nogil=True)
def _image_to_ground_kernel(
    col: np.ndarray,
    row: np.ndarray,
    h: np.ndarray,
    coef: np.ndarray,
    nrm: np.ndarray,
    px_tol: float,
    deg_tol: float,
    max_iter: int,
    lon: np.ndarray,
    lat: np.ndarray,
    status: np.ndarray,
) -> None:
    """(lon, lat) of image points (col, row) at heights h; NaN in, NaN out (status 0)."""
    for i in range(col.size):
        if math.isnan(col[i]) or math.isnan(row[i]) or math.isnan(h[i]):
            lon[i] = math.nan
            lat[i] = math.nan
            status[i] = 0
        else:
            lon[i], lat[i], status[i] = _image_to_ground_one(coef, nrm, col[i], row[i], h[i], px_tol, deg_tol, max_iter)


# ---------------------------------------------------------------------------------------------
# coefficients and model
# ---------------------------------------------------------------------------------------------


def _metadata_error(source: str, what: str) -> MetadataError:
    return MetadataError(
        f"{source}: {what}. The RPC cannot be used; check the file or export the "
        "RPC again from the product's original metadata."
    )


def _number(text: str | float, key: str, source: str) -> float:
    """A finite float from a number or a text whose first token is one ('+018339.50 pixels')."""
    token = text.split()[0] if isinstance(text, str) and text.split() else text
    try:
        value = float(token)
    except (TypeError, ValueError):
        raise _metadata_error(source, f"{key} is not a number: {str(text)[:40]!r}") from None
    if not math.isfinite(value):
        raise _metadata_error(source, f"{key} is not finite ({value})")
    return value


def _coefficient_list(value: str | ArrayLike, key: str, source: str) -> np.ndarray:
    """20 finite floats from a text of numbers separated by blanks or commas, or a sequence."""
    items = value.replace(",", " ").split() if isinstance(value, str) else list(np.atleast_1d(value))
    if len(items) != NUM_TERMS:
        raise _metadata_error(source, f"{key} has {len(items)} values; RPC00B needs {NUM_TERMS}")
    return np.array([_number(v, f"{key}[{i + 1}]", source) for i, v in enumerate(items)])


def _check_domain(arrays: Mapping[str, np.ndarray], values: Mapping[str, float], source: str) -> None:
    """MetadataError unless, on the domain_grid, both denominators keep one sign and the image
    coordinates are finite (module docstring); the message names the first grid point (nearest the
    centre) where the sign differs from the centre's."""
    x, y, z = domain_grid()
    t = rpc_terms(x, y, z)
    with np.errstate(all="ignore"):
        ground = (
            values["long_off"] + x * values["long_scale"],
            values["lat_off"] + y * values["lat_scale"],
            values["height_off"] + z * values["height_scale"],
        )

    def where(i: int) -> str:
        return f"lon {ground[0][i]:.6f}, lat {ground[1][i]:.6f}, h {ground[2][i]:.0f} m"

    lon, lat, h = (
        np.sort([a - abs(s), a + abs(s)])
        for a, s in (
            (values["long_off"], values["long_scale"]),
            (values["lat_off"], values["lat_scale"]),
            (values["height_off"], values["height_scale"]),
        )
    )
    domain = (
        f"the RPC's validity domain (lon {lon[0]:.6f} .. {lon[1]:.6f}, lat {lat[0]:.6f} .. {lat[1]:.6f}, "
        f"h {h[0]:.0f} .. {h[1]:.0f} m)"
    )
    centre = x.size // 2
    for name, coordinate in (("line", "row"), ("samp", "column")):
        with np.errstate(all="ignore"):
            den = t @ arrays[f"{name}_den"]
            image = (t @ arrays[f"{name}_num"]) / den * values[f"{name}_scale"] + values[f"{name}_off"]
        if np.all(np.isfinite(den)) and not keeps_sign(den):
            other = np.sign(den) != np.sign(den[centre])
            i = np.flatnonzero(other)[np.argmin((x * x + y * y + z * z)[other])]
            pole = "there" if den[i] == 0.0 else "in between"
            raise _metadata_error(
                source,
                f"{name.upper()}_DEN_COEFF, the denominator of the image {coordinate}, changes sign within "
                f"{domain}: it is {den[centre]:+.3g} at the centre ({where(centre)}) and {den[i]:+.3g} at "
                f"{where(i)}, so the {coordinate} has a pole {pole} and image positions near it are wrong "
                "by any amount",
            )
        if not np.all(np.isfinite(image)):
            i = np.flatnonzero(~np.isfinite(image))[0]
            raise _metadata_error(
                source,
                f"the image {coordinate} is not a finite number at {where(i)}, within "
                f"{domain}: coefficients, offsets or scales out of range",
            )


def _check_geometry(
    arrays: Mapping[str, np.ndarray], values: Mapping[str, float], source: str, pixel_shape: bool = False
) -> None:
    """MetadataError unless the RPC's values describe an image of a place on Earth (module docstring), and with
    `pixel_shape` (an RPC read from a file) near-square pixels at its centre; the message names the value at
    fault."""
    for key in SCALE_KEYS:
        if not values[key.lower()] > 0.0:
            raise _metadata_error(
                source, f"{key} is {values[key.lower()]:g}: a scale is the positive half-range of its coordinate"
            )
    lat, lon = values["lat_off"], values["long_off"]
    swapped = " (LAT_OFF and LONG_OFF swapped?)" if abs(lon) <= 90.0 else ""
    if abs(lat) > 90.0 or abs(lat) + values["lat_scale"] > 90.0:
        raise _metadata_error(
            source,
            f"LAT_OFF {lat:g} +- LAT_SCALE {values['lat_scale']:g} is no latitude range (-90 .. 90 degrees){swapped}",
        )
    if not -180.0 <= lon <= 360.0:
        raise _metadata_error(source, f"LONG_OFF {lon:g} is no longitude (-180 .. 360 degrees)")
    for name, coordinate in (("line", "row"), ("samp", "column")):
        if not arrays[f"{name}_num"].any():
            raise _metadata_error(
                source,
                f"{name.upper()}_NUM_COEFF is all zeros: every ground point would have the same image {coordinate}",
            )
    if arrays["samp_den"][0] == 0.0 or arrays["line_den"][0] == 0.0:
        return  # from_fields names a denominator vanishing at the centre
    sides = _pixel_sides(arrays, values)
    if sides is None:
        return  # _check_domain names image coordinates that overflow
    if not sides[1] > 1e-6 * sides[0]:  # a footprint a million times longer than wide: a line
        raise _metadata_error(
            source,
            "the image column and row change along one ground direction only: the "
            "numerators (SAMP_NUM_COEFF, LINE_NUM_COEFF) describe no image of the ground",
        )
    if pixel_shape and sides[0] / sides[1] > MAX_PIXEL_ELONGATION:
        raise _metadata_error(
            source,
            f"its pixels would cover {1 / sides[1]:.3g} x {1 / sides[0]:.3g} m on the "
            f"ground at its centre, {sides[0] / sides[1]:.1f} times longer than wide: the "
            "ground offsets and scales do not belong to its coefficients (LAT_OFF and "
            "LONG_OFF swapped, or LAT_SCALE and LONG_SCALE?)",
        )


def _pixel_sides(arrays: Mapping[str, np.ndarray], values: Mapping[str, float]) -> np.ndarray | None:
    """(longest, shortest) of 1 / the pixel footprint's sides at the ground centre, px per metre: the singular
    values of d(col, row)/d(east, north), _partials_kernel's derivatives (px/deg) over the metres per degree
    there; None where they are no finite numbers (coefficients near the float range's end)."""
    coef = np.array([arrays["line_num"], arrays["line_den"], arrays["samp_num"], arrays["samp_den"]])
    nrm = np.array(
        [
            values["long_off"],
            values["long_scale"],
            values["lat_off"],
            values["lat_scale"],
            values["height_off"],
            values["height_scale"],
            0.0,
            values["samp_scale"],
            0.0,
            values["line_scale"],
        ]
    )
    centre = [np.array([values[k]]) for k in ("long_off", "lat_off", "height_off")]
    derivatives = np.empty((1, 2, 3))
    _partials_kernel(*centre, coef, nrm, derivatives)
    with np.errstate(over="ignore", invalid="ignore"):
        jacobian = derivatives[0, :, :2] / np.array(metres_per_degree(values["lat_off"], values["height_off"]))
    return np.linalg.svd(jacobian, compute_uv=False) if np.isfinite(jacobian).all() else None


@dataclass(frozen=True, eq=False)
class RpcCoefficients:
    """The 90 RPC00B values as in the file: polynomial coefficients in RPC00B term order, offsets
    and scales; LINE_OFF/SAMP_OFF in RPC00B's convention (first pixel centre at (0, 0)) of the
    image the RPC describes."""

    line_num: np.ndarray
    line_den: np.ndarray
    samp_num: np.ndarray
    samp_den: np.ndarray
    line_off: float
    samp_off: float
    lat_off: float
    long_off: float
    height_off: float
    line_scale: float
    samp_scale: float
    lat_scale: float
    long_scale: float
    height_scale: float

    @classmethod
    def from_fields(cls, fields: Mapping[str, Any], source: str = "RPC", pixel_shape: bool = False) -> RpcCoefficients:
        """Parse and check a mapping with the RPC00B (GDAL metadata) names: LINE_OFF ... as numbers
        or texts, LINE_NUM_COEFF ... as 20 numbers (text or sequence). `source` names the origin
        in error messages. Raises MetadataError on missing, non-numeric, non-finite,
        wrong-count values, values that describe no image of a place on Earth (_check_geometry; with
        `pixel_shape`, the check of an RPC read from a file, also pixels far from square), a
        denominator that vanishes at the normalisation centre or changes sign within the validity domain,
        or image coordinates that are not finite there (module docstring)."""
        missing = [k for k in OFFSET_KEYS + SCALE_KEYS + COEFF_KEYS if k not in fields]
        if missing:
            raise _metadata_error(source, f"missing {', '.join(missing)}")
        values = {k.lower(): _number(fields[k], k, source) for k in OFFSET_KEYS + SCALE_KEYS}
        arrays = {k.lower()[:8]: _coefficient_list(fields[k], k, source) for k in COEFF_KEYS}
        _check_geometry(arrays, values, source, pixel_shape)
        for key in ("line_den", "samp_den"):
            if arrays[key][0] == 0.0:
                raise _metadata_error(
                    source, f"{key.upper()}_COEFF vanishes at the normalisation centre (its first coefficient is 0)"
                )
        _check_domain(arrays, values, source)
        for a in arrays.values():
            a.setflags(write=False)
        parts: dict[str, Any] = {**arrays, **values}  # arrays and floats: mypy checks ** values against every field
        return cls(**parts)

    def to_fields(self, col0: float = 0.0, row0: float = 0.0) -> dict[str, str]:
        """GDAL 'RPC' metadata (name -> text, exact float repr), LINE_OFF/SAMP_OFF shifted to a
        crop whose top-left corner is at (col0, row0) of the image the RPC describes."""
        values = {
            "LINE_OFF": self.line_off - row0,
            "SAMP_OFF": self.samp_off - col0,
            "LAT_OFF": self.lat_off,
            "LONG_OFF": self.long_off,
            "HEIGHT_OFF": self.height_off,
            "LINE_SCALE": self.line_scale,
            "SAMP_SCALE": self.samp_scale,
            "LAT_SCALE": self.lat_scale,
            "LONG_SCALE": self.long_scale,
            "HEIGHT_SCALE": self.height_scale,
        }
        fields = {k: repr(float(v)) for k, v in values.items()}
        for key, array in zip(COEFF_KEYS, (self.line_num, self.line_den, self.samp_num, self.samp_den)):
            fields[key] = " ".join(repr(float(v)) for v in array)
        return fields


class RpcModel(SensorModel):
    """RPC00B model in GDAL's pixel convention on a raster whose top-left corner lies at
    `offset` = (col0, row0) of the image the RPC describes (module docstring).

    `size` is the raster's (cols, rows); where no raster is known it is estimated as the upper end
    of the RPC's image normalisation, ceil(SAMP_OFF + 0.5 + |SAMP_SCALE| - col0) and likewise for
    rows (the RPC's validity domain); MetadataError where that is not a positive size."""

    #: d_corrections columns of an exterior orientation: none (the bias acts in image space)
    EXTERIOR_COEFFICIENTS = 0
    #: SensorModel.location_sigma (m): RPC00B's ERR_BIAS is mostly -1 (unknown), so a bound looser than the stated
    #: accuracy of the RPC products this model reads (Pleiades 8.5 m CE90, WorldView under 5 m CE90): 25 m per axis,
    #: about 54 m CE90
    location_sigma = 25.0
    size: tuple[int, int]

    def __init__(
        self,
        coefficients: RpcCoefficients,
        size: Sequence[int] | None = None,
        offset: Sequence[float] = (0.0, 0.0),
        source: str = "RPC",
        bias: ArrayLike | None = None,
    ) -> None:
        self.coefficients = coefficients
        self.bias = np.zeros(6) if bias is None else np.asarray(bias, float).reshape(6)
        self.offset = (float(offset[0]), float(offset[1]))
        self.source = str(source)
        c = coefficients
        col0, row0 = self.offset
        self._coef = np.array([c.line_num, c.line_den, c.samp_num, c.samp_den])
        self._nrm = np.array(
            [
                c.long_off,
                c.long_scale,
                c.lat_off,
                c.lat_scale,
                c.height_off,
                c.height_scale,
                c.samp_off + 0.5 - col0,
                c.samp_scale,
                c.line_off + 0.5 - row0,
                c.line_scale,
            ]
        )
        if size is None:
            size = (
                math.ceil(c.samp_off + 0.5 + abs(c.samp_scale) - col0),
                math.ceil(c.line_off + 0.5 + abs(c.line_scale) - row0),
            )
            if min(size) < 1:
                raise _metadata_error(
                    self.source,
                    f"SAMP_OFF + SAMP_SCALE, LINE_OFF + LINE_SCALE describe an image of {size[0]} x {size[1]} pixels",
                )
        self.size = (int(size[0]), int(size[1]))

    def __repr__(self) -> str:
        return f"RpcModel({self.source!r}, size={self.size}, offset={self.offset})"

    # -- readers (formats in rpc_io) ------------------------------------------------------------

    @classmethod
    def _from_record(cls, record: rpc_io.RpcRecord) -> RpcModel:
        coefficients = RpcCoefficients.from_fields(record.fields, record.source, pixel_shape=True)
        return cls(coefficients, record.size, record.offset, record.source)

    @classmethod
    def from_raster(cls, path: str | os.PathLike[str]) -> RpcModel:
        """RPC of a raster as GDAL reads it (metadata domain 'RPC': GeoTIFF RPC tags, or _RPC.TXT /
        .RPB beside it). A same-stem OSSIM .geom beside a raster is found by sensors.load through
        sensors.orientation_source and read by from_geom."""
        return cls._from_record(rpc_io.read_raster(path))

    @classmethod
    def from_rpc_file(cls, path: str | os.PathLike[str]) -> RpcModel:
        """RPC of a _RPC.TXT or .RPB file, parsed directly; the size is that of a same-stem raster
        beside it, if there is one."""
        return cls._from_record(rpc_io.read_rpc_file(path))

    @classmethod
    def from_geom(cls, path: str | os.PathLike[str], image: str | os.PathLike[str] | None = None) -> RpcModel:
        """RPC of an OSSIM/OTB .geom keyword list (OSSIM's image coordinates are RPC00B's: first
        pixel centre at (0, 0); polynomial_format A is reordered to RPC00B). `image` (default: a
        same-stem raster beside it, if any) is the raster the model refers to; its geotransform
        origin, a pure pixel translation as OTB writes for an extract, is the crop offset (col0,
        row0). Without a raster the model describes the full image (number_samples, number_lines)."""
        return cls._from_record(rpc_io.read_geom(path, image))

    def to_fields(self) -> dict[str, str]:
        """GDAL 'RPC' metadata of this model on its own raster (offsets shifted by the crop)."""
        return self.coefficients.to_fields(*self.offset)

    # -- geometry -----------------------------------------------------------------------------------

    @property
    def height_range(self) -> tuple[float, float]:
        """(min, max) ellipsoidal height of the RPC's validity domain: HEIGHT_OFF -+ HEIGHT_SCALE."""
        c = self.coefficients
        return c.height_off - abs(c.height_scale), c.height_off + abs(c.height_scale)

    def ground_to_image(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """(col, row) of ground points (lon, lat, h): direct evaluation of the rational functions."""
        (lo, la, hh), shape, scalar = flat_points(lon, lat, h)
        col = np.empty(lo.size)
        row = np.empty(lo.size)
        _ground_to_image_kernel(lo, la, hh, self._coef, self._nrm, col, row)
        if self.bias.any():
            col, row = self._biased(col, row)
        return shaped_points((col, row), shape, scalar)

    def _bias_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """(J, t): biased = J @ (col, row) + t, the bias as an affine map of the image coordinates."""
        a0, a1, a2, b0, b1, b2 = self.bias
        cc, rc = 0.5 * self.size[0], 0.5 * self.size[1]
        jac = np.array([[1.0 + a1 / 1000.0, a2 / 1000.0], [b1 / 1000.0, 1.0 + b2 / 1000.0]])
        t = np.array([a0, b0]) - (jac - np.eye(2)) @ np.array([cc, rc])
        return jac, t

    def _biased(self, col: np.ndarray, row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        jac, t = self._bias_matrix()
        return jac[0, 0] * col + jac[0, 1] * row + t[0], jac[1, 0] * col + jac[1, 1] * row + t[1]

    def _image_to_ground(
        self, col: ArrayLike, row: ArrayLike, h: ArrayLike
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[int, ...], bool]:
        """(col, row of the unbiased RPC, h, lon, lat, status, shape, scalar) of image points (flat
        arrays; shape and scalar as flat_points); status 0 = converged, 1 = not converged,
        2 = singular Jacobian (lon/lat then undefined)."""
        (c, r, hh), shape, scalar = flat_points(col, row, h)
        if self.bias.any():
            jac, t = self._bias_matrix()
            c, r = np.linalg.solve(jac, np.vstack([c - t[0], r - t[1]]))
            c, r = np.ascontiguousarray(c), np.ascontiguousarray(r)
        lon = np.empty(c.size)
        lat = np.empty(c.size)
        status = np.empty(c.size, dtype=np.int8)
        _image_to_ground_kernel(c, r, hh, self._coef, self._nrm, PX_TOL, DEG_TOL, MAX_ITER, lon, lat, status)
        return c, r, hh, lon, lat, status, shape, scalar

    def image_to_ground(self, col: ArrayLike, row: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """(lon, lat) of image points at ellipsoidal heights h, by Newton's method on the rational
        functions (analytic Jacobian, step halving), started at (LONG_OFF, LAT_OFF) and iterated to
        below 1e-8 px and 1e-10 deg. Raises GeometryError where it does not converge."""
        c, r, hh, lon, lat, status, shape, scalar = self._image_to_ground(col, row, h)
        bad = np.flatnonzero(status)
        if bad.size:
            i = bad[0]
            raise GeometryError(
                f"{self.source}: no ground point found for {bad.size} of {c.size} image points, "
                f"e.g. ({c[i]:.2f}, {r[i]:.2f}) at height {hh[i]:.1f} m: the iteration "
                f"{'did not converge' if status[i] == 1 else 'met a singular Jacobian'}. Is the point "
                f"inside the image ({self.size[0]} x {self.size[1]} px) and the height within the "
                f"RPC's range {self.height_range[0]:.0f} .. {self.height_range[1]:.0f} m?"
            )
        return shaped_points((lon, lat), shape, scalar)

    def image_to_ground_or_nan(self, col: ArrayLike, row: ArrayLike, h: ArrayLike) -> tuple[Coordinate, Coordinate]:
        """image_to_ground with NaN where the iteration fails."""
        _, _, _, lon, lat, status, shape, scalar = self._image_to_ground(col, row, h)
        lon[status != 0] = np.nan
        lat[status != 0] = np.nan
        return shaped_points((lon, lat), shape, scalar)

    def partials(self, lon: ArrayLike, lat: ArrayLike, h: ArrayLike, exterior: bool = True) -> dict[str, np.ndarray]:
        """Image coordinates of ground points and their partial derivatives, as SpotModel.partials
        (`exterior` is accepted for the common interface: an RPC model has no exterior orientation):
        a dict of col, row (...); d_ground (..., 2, 3) = d(col, row)/d(lon, lat, h) in px/deg,
        px/deg, px/m (quotient rule on the rational functions, through the bias); d_corrections
        (..., 2, 6) = d(col, row)/d(bias) (A0, A1, A2, B0, B1, B2; module docstring)."""
        (lo, la, hh), shape, _ = flat_points(lon, lat, h)
        col, row = np.empty(lo.size), np.empty(lo.size)
        _ground_to_image_kernel(lo, la, hh, self._coef, self._nrm, col, row)
        d_ground = np.empty((lo.size, 2, 3))
        _partials_kernel(lo, la, hh, self._coef, self._nrm, d_ground)
        u, v = (col - 0.5 * self.size[0]) / 1000.0, (row - 0.5 * self.size[1]) / 1000.0
        d_bias = np.zeros((lo.size, 2, 6))
        d_bias[:, 0, 0], d_bias[:, 0, 1], d_bias[:, 0, 2] = 1.0, u, v
        d_bias[:, 1, 3], d_bias[:, 1, 4], d_bias[:, 1, 5] = 1.0, u, v
        if self.bias.any():
            col, row = self._biased(col, row)
            d_ground = np.einsum("ij,njk->nik", self._bias_matrix()[0], d_ground)
        return {
            "col": col.reshape(shape),
            "row": row.reshape(shape),
            "d_ground": d_ground.reshape(shape + (2, 3)),
            "d_corrections": d_bias.reshape(shape + (2, 6)),
        }
