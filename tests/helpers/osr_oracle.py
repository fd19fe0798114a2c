"""Independent oracles through OSR for tests (point by point, not the engine's array transforms)."""

import numpy as np
from osgeo import osr


def utm(lon, lat, epsg):
    """(x, y) of WGS 84 lon/lat in the UTM zone `epsg`, one OSR TransformPoint per point."""
    wgs84, target = osr.SpatialReference(), osr.SpatialReference()
    wgs84.ImportFromEPSG(4326)
    target.ImportFromEPSG(epsg)
    for srs in (wgs84, target):
        srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ct = osr.CoordinateTransformation(wgs84, target)
    return np.array([ct.TransformPoint(float(a), float(b))[:2] for a, b in zip(lon, lat)]).T
