"""The simulator's ground grid: a north-up WGS 84 longitude/latitude raster (EPSG:4326, heights
ellipsoidal) with GDAL's pixel-is-area geotransform, shared by the DTM, DSM, land cover and
radiance. Kernels address it in *vertex* coordinates x = (lon - lon0)/dlon - 0.5,
y = (lat - lat0)/dlat - 0.5, so the cell (i, j) centre is the vertex (x=j, y=i) and bilinear
interpolation runs between centres (as in algorithms/dem.py)."""

import math
from dataclasses import dataclass

import numpy as np

from ..dem import grid_bounds
from ..geodesy import metres_per_degree


@dataclass(frozen=True)
class Grid:
    """Regular geographic grid: `rows` x `cols` cells of dlon x |dlat| degrees from the
    north-west corner (lon0, lat0)."""

    lon0: float
    dlon: float
    lat0: float
    dlat: float  # negative (north-up)
    cols: int
    rows: int

    @classmethod
    def covering(cls, bounds, cell_m):
        """The grid of ~`cell_m` metre square cells covering (lon_min, lat_min, lon_max, lat_max)."""
        lon_min, lat_min, lon_max, lat_max = bounds
        me, mn = metres_per_degree(0.5 * (lat_min + lat_max))
        dlon = cell_m / me
        dlat = cell_m / mn
        cols = int(math.ceil((lon_max - lon_min) / dlon))
        rows = int(math.ceil((lat_max - lat_min) / dlat))
        return cls(lon_min, dlon, lat_max, -dlat, cols, rows)

    @property
    def shape(self):
        return self.rows, self.cols

    @property
    def geotransform(self):
        return (self.lon0, self.dlon, 0.0, self.lat0, 0.0, self.dlat)

    @property
    def bounds(self):
        """(lon_min, lat_min, lon_max, lat_max) of the outer cell edges."""
        return grid_bounds(self.geotransform, self.shape)

    @property
    def centre(self):
        lon_min, lat_min, lon_max, lat_max = self.bounds
        return 0.5 * (lon_min + lon_max), 0.5 * (lat_min + lat_max)

    @property
    def cell_metres(self):
        """(east, north) size of a cell in metres at the grid centre."""
        me, mn = metres_per_degree(self.centre[1])
        return self.dlon * me, -self.dlat * mn

    def window(self, i0, i1, j0, j1):
        """The grid of rows i0..i1 and columns j0..j1 of this one."""
        return Grid(self.lon0 + j0 * self.dlon, self.dlon, self.lat0 + i0 * self.dlat, self.dlat, j1 - j0, i1 - i0)

    def vertex(self, lon, lat):
        """Vertex coordinates (x, y) of (lon, lat)."""
        return ((np.asarray(lon) - self.lon0) / self.dlon - 0.5, (np.asarray(lat) - self.lat0) / self.dlat - 0.5)

    def lonlat(self, x, y):
        """(lon, lat) of vertex coordinates (x, y)."""
        return self.lon0 + (np.asarray(x) + 0.5) * self.dlon, self.lat0 + (np.asarray(y) + 0.5) * self.dlat

    def local_metres(self):
        """(e0, de, n0, dn): cell (i, j) centre lies at east e0 + j de, north n0 - i dn metres from
        the grid centre (a local equirectangular frame for procedural textures)."""
        de, dn = self.cell_metres
        return -0.5 * (self.cols - 1) * de, de, 0.5 * (self.rows - 1) * dn, dn
