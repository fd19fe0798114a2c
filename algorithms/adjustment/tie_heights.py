"""Heights of the adjusted tie points against a reference DTM (Kornus et al. 2006, section 3.4.3.1, Table 4):
dh = adjusted ellipsoidal height - reference height, the reference interpolated bilinearly at the
point's lon/lat (dem.Dem.height). A reference in EGM96 orthometric heights H (SRTM) becomes
ellipsoidal at the point, h = H + N (control_points.orthometric_to_ellipsoidal)."""

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .control_points import HEIGHT_TYPES, orthometric_to_ellipsoidal


@dataclass
class TieHeights:
    names: np.ndarray  # tie points inside the DEM
    dh: np.ndarray  # adjusted - reference (m)
    outside: int  # tie points where the DEM has no height (outside it or next to nodata)


def tie_height_differences(result, dem, heights="ellipsoidal"):
    """TieHeights of the tie points of Adjustment `result` against `dem` (dem.Dem or dem_store.StoredDem: its
    `height`) whose heights are `heights` (control_points.HEIGHT_TYPES: "ellipsoidal" or "orthometric", EGM96)."""
    if heights not in HEIGHT_TYPES:
        raise InputError(f"reference heights {heights!r}: choose one of {', '.join(HEIGHT_TYPES)}")
    tie = result.observations.points["role"] == "tie"
    lon, lat, h = result.lon[tie], result.lat[tie], result.h[tie]
    reference = np.atleast_1d(dem.height(lon, lat))
    inside = np.isfinite(reference) & np.isfinite(h)
    if heights == "orthometric" and inside.any():
        reference[inside] = orthometric_to_ellipsoidal(lon[inside], lat[inside], reference[inside])
    return TieHeights(
        result.observations.points["name"][tie][inside], h[inside] - reference[inside], int((~inside).sum())
    )
