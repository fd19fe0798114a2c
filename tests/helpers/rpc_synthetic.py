"""A synthetic Pleiades-like RPC00B, a plain numpy reference of its evaluation and small file
writers, for the RPC tests that must not depend on the real test data."""

import numpy as np
from osgeo import gdal

from pushbroom.algorithms.sensors.rpc import RpcCoefficients

#: exponents of (L, P, H) of the 20 terms in RPC00B order (NITF STDI-0002)
B_EXPONENTS = [
    (0, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 1, 0),
    (1, 0, 1),
    (0, 1, 1),
    (2, 0, 0),
    (0, 2, 0),
    (0, 0, 2),
    (1, 1, 1),
    (3, 0, 0),
    (1, 2, 0),
    (1, 0, 2),
    (2, 1, 0),
    (0, 3, 0),
    (0, 1, 2),
    (2, 0, 1),
    (0, 2, 1),
    (0, 0, 3),
]
#: the same for OSSIM's polynomial_format A (ossimRpcModel::polynomial)
A_EXPONENTS = [
    (0, 0, 0),
    (1, 0, 0),
    (0, 1, 0),
    (0, 0, 1),
    (1, 1, 0),
    (1, 0, 1),
    (0, 1, 1),
    (1, 1, 1),
    (2, 0, 0),
    (0, 2, 0),
    (0, 0, 2),
    (3, 0, 0),
    (2, 1, 0),
    (2, 0, 1),
    (1, 2, 0),
    (0, 3, 0),
    (0, 2, 1),
    (1, 0, 2),
    (0, 1, 2),
    (0, 0, 3),
]

SCALARS = {
    "LINE_OFF": 20900.0,
    "SAMP_OFF": 19590.5,
    "LAT_OFF": 44.137,
    "LONG_OFF": 5.2846,
    "HEIGHT_OFF": 1075.0,
    "LINE_SCALE": 21137.5,
    "SAMP_SCALE": 19999.5,
    "LAT_SCALE": 0.099,
    "LONG_SCALE": 0.1287,
    "HEIGHT_SCALE": 885.0,
}


def synthetic_fields(seed=0):
    """RPC00B fields (numbers) of a near-affine pushbroom-like RPC with small cubic terms."""
    rng = np.random.default_rng(seed)

    def cubic(constant_and_linear, spread):
        return list(constant_and_linear) + list(rng.normal(0.0, spread, 16))

    return dict(
        SCALARS,
        LINE_NUM_COEFF=cubic([5e-5, 0.0204, -1.032, 0.0121], 2e-5),
        LINE_DEN_COEFF=cubic([1.0, 3e-4, 1e-4, -3e-5], 2e-6),
        SAMP_NUM_COEFF=cubic([-4.3e-3, 1.0192, 0.0168, -3.5e-3], 2e-5),
        SAMP_DEN_COEFF=cubic([1.0, 1.8e-3, 1e-3, -7e-4], 2e-6),
    )


def synthetic_coefficients(seed=0):
    return RpcCoefficients.from_fields(synthetic_fields(seed), "synthetic")


def numpy_ground_to_image(fields, lon, lat, h, col0=0.0, row0=0.0):
    """Plain numpy RPC00B: terms as monomials from B_EXPONENTS; GDAL pixel convention (+0.5)."""
    x = (np.asarray(lon) - fields["LONG_OFF"]) / fields["LONG_SCALE"]
    y = (np.asarray(lat) - fields["LAT_OFF"]) / fields["LAT_SCALE"]
    z = (np.asarray(h) - fields["HEIGHT_OFF"]) / fields["HEIGHT_SCALE"]
    terms = np.stack([x**i * y**j * z**k for i, j, k in B_EXPONENTS], axis=-1)

    def ratio(num, den):
        return terms @ np.asarray(num, float) / (terms @ np.asarray(den, float))

    col = ratio(fields["SAMP_NUM_COEFF"], fields["SAMP_DEN_COEFF"]) * fields["SAMP_SCALE"] + fields["SAMP_OFF"] + 0.5
    row = ratio(fields["LINE_NUM_COEFF"], fields["LINE_DEN_COEFF"]) * fields["LINE_SCALE"] + fields["LINE_OFF"] + 0.5
    return col - col0, row - row0


def geom_text(fields, polynomial_format="B", size=(39182, 41801)):
    """An OSSIM keyword list (.geom) holding `fields`; coefficients converted to format A if asked."""
    lines = [
        "type:  ossimRpcModel",
        f"polynomial_format:  {polynomial_format}",
        f"number_samples:  {size[0]}",
        f"number_lines:  {size[1]}",
    ]
    lines += [f"{k.lower()}:  {v!r}" for k, v in fields.items() if not k.endswith("COEFF")]
    for key in ("LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"):
        b = list(fields[key])
        coeffs = b if polynomial_format == "B" else [b[B_EXPONENTS.index(e)] for e in A_EXPONENTS]
        lines += [f"{key.lower()[:8]}_coeff_{j:02d}:  {float(v)!r}" for j, v in enumerate(coeffs)]
    return "\n".join(lines) + "\n"


def write_raster(path, size=(64, 48), geotransform=None, rpc=None):
    """A small GeoTIFF (no pixels of interest), optionally with a geotransform and RPC tags."""
    ds = gdal.GetDriverByName("GTiff").Create(str(path), size[0], size[1], 1, gdal.GDT_Byte)
    if geotransform is not None:
        ds.SetGeoTransform(geotransform)
    if rpc is not None:
        ds.SetMetadata(
            {
                k: v if isinstance(v, str) else " ".join(repr(float(x)) for x in np.atleast_1d(v))
                for k, v in rpc.items()
            },
            "RPC",
        )
    ds = None
    return path


#: an affine Pleiades-like RPC (row from latitude, column from longitude) over 0.1 x 0.1 degrees
AFFINE = {
    "LINE_OFF": 500.0,
    "SAMP_OFF": 500.0,
    "LAT_OFF": 44.1,
    "LONG_OFF": 5.2,
    "HEIGHT_OFF": 500.0,
    "LINE_SCALE": 500.0,
    "SAMP_SCALE": 500.0,
    "LAT_SCALE": 0.05,
    "LONG_SCALE": 0.05,
    "HEIGHT_SCALE": 500.0,
    "LINE_NUM_COEFF": [0.0, 0.0, -1.0] + [0.0] * 17,
    "SAMP_NUM_COEFF": [0.0, 1.0] + [0.0] * 18,
    "LINE_DEN_COEFF": [1.0] + [0.0] * 19,
    "SAMP_DEN_COEFF": [1.0] + [0.0] * 19,
}


def raster_with_rpc(path, **changes):
    """A 1000 x 1000 GeoTIFF with the AFFINE RPC (with `changes`) in its RPC tags."""
    return write_raster(path, size=(1000, 1000), rpc=dict(AFFINE, **changes))
