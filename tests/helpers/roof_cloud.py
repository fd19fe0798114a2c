"""A LAS cloud of a roof ridge with its breakline, shared by the interpolatedem and COG tests."""

import numpy as np
from osgeo import ogr

from pushbroom.algorithms.crs import srs, transform
from pushbroom.algorithms.surface import pointcloud

UTM31 = 32631


def roof_cloud(folder, n=4000):
    """A LAS cloud of a ridge z = h0 - 0.5 |x - xr| (ellipsoidal) in UTM 31N with sigma_h, and a GeoPackage
    with the ridge as a 3-D breakline. Returns (las, breaklines, roof(x))."""
    rng = np.random.default_rng(0)
    x, y = 650_000 + rng.uniform(0, 1000, n), 4_890_000 + rng.uniform(0, 1000, n)
    roof = lambda px: 400 - 0.5 * np.abs(px - 650_500)
    lon, lat = transform(srs(UTM31), srs(4326), np.column_stack([x, y]), "the test points")[:, :2].T
    las, _, _ = pointcloud.write_point_cloud(
        folder / "cloud.las", lon, lat, roof(x), {"sigma_h": np.full(n, 0.4, np.float32)}, crs=UTM31
    )
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(folder / "lines.gpkg"))
    layer = ds.CreateLayer("ridge", srs(UTM31), ogr.wkbLineString25D)
    feature = ogr.Feature(layer.GetLayerDefn())
    feature.SetGeometry(ogr.CreateGeometryFromWkt("LINESTRING Z (650500 4889990 400, 650500 4891010 400)"))
    layer.CreateFeature(feature)
    ds = None
    return las, str(folder / "lines.gpkg"), roof
