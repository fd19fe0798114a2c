"""The DSM of a matcher's points against the simulator's true DSM, by class (issue 7's acceptance,
test_coarse_to_fine.py): the points are intersected with the TRUTH models (the error is the
matcher's alone, not the supplied models' orientation error, which the chain's adjustment would
remove), gridded as the chain does (surface/tin_dem.interpolate_dem, 10 m UTM cells, its blunder
filter) but with one maximum triangle edge for both strategies, MAX_EDGE_M (the chain's default
for region growing's 10 px HRG lattice: 2.5 x 50 m; the default shrinks with the median point
spacing, and the coarse-to-fine matcher's Foerstner points between its grid points would make its
gaps larger than region growing's at the same lattice), and the DEM sampled at the centres of
the 10 m cells seen by all three images (12 px inside each), compared with the true DSM there
(bilinear).

Classes per cell: the simulator's land cover with the open classes split by texture as
end_to_end_chain.py does (ground std over a 95 m window < LOW_CONTRAST_DN: LOW_TEXTURE), and a
building-edge zone: cells within EDGE_M (2 HRG pixels, 10 m) of a building outline; a building is a
connected set of city cells whose DSM stands more than BUILDING_M above the DTM; and the open cells (bare,
crops, low texture) within EDGE_M of forest, city or water, where a matching window straddles two surfaces."""

import numpy as np
from osgeo import gdal
from scipy import ndimage

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.simulation.terrain import BARE, CITY, CROPS, FOREST, WATER
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.point_input import PointSet
from pushbroom.algorithms.surface.pointcloud import output_srs
from pushbroom.algorithms.surface.tin_dem import DemParams, interpolate_dem
from tests.helpers.matching_scene import LOW_CONTRAST_DN

NAMES = ("HRG", "HRS1", "HRS2")
CELL = 10.0
LOW_TEXTURE = 6
CLASSES = {BARE: "bare", CROPS: "crops", LOW_TEXTURE: "low-tex", FOREST: "forest", CITY: "city"}
EDGE = 100  # pseudo class: building-edge zone
NEAR = "open near forest/city/water"
EDGE_M = 10.0  # 2 HRG pixels
BUILDING_M = 2.0
MARGIN_PX = 12.0
MAX_EDGE_M = 125.0


class Truth:
    """Evaluation cells of the small scene (module docstring): centres (x, y UTM), true height, class, edge zone."""

    def __init__(self, paths):
        self.models = {k + 1: sensors.load(paths["truth_metadata"][n]) for k, n in enumerate(NAMES)}
        self.dsm = read_dem(paths["dsm"])
        dtm = read_dem(paths["dtm"])
        lon0, lat0, lon1, lat1 = self.dsm.bounds
        self.srs = output_srs(None, np.array([0.5 * (lon0 + lon1)]), np.array([0.5 * (lat0 + lat1)]))
        corners = reproject(np.array([lon0, lon1, lon0, lon1]), np.array([lat0, lat0, lat1, lat1]), wgs84(), self.srs)
        xs = np.arange(np.floor(corners[0].min() / CELL), np.ceil(corners[0].max() / CELL)) * CELL + CELL / 2
        ys = np.arange(np.floor(corners[1].min() / CELL), np.ceil(corners[1].max() / CELL)) * CELL + CELL / 2
        x, y = (v.ravel() for v in np.meshgrid(xs, ys))
        lon, lat = reproject(x, y, self.srs, wgs84())
        h = self.dsm.height(lon, lat)
        seen = np.isfinite(h)
        for model in self.models.values():
            c, r = model.ground_to_image(lon, lat, np.nan_to_num(h))
            cols, rows = model.size
            seen &= (c > MARGIN_PX) & (c < cols - MARGIN_PX) & (r > MARGIN_PX) & (r < rows - MARGIN_PX)
        self.x, self.y, self.h = x[seen], y[seen], h[seen]
        lon, lat = lon[seen], lat[seen]
        self.dtm_h = dtm.height(lon, lat)
        ds = gdal.Open(str(paths["classes"]))
        land, gt = ds.ReadAsArray(), ds.GetGeoTransform()
        ds = None
        ortho = gdal.Open(str(paths["orthoimage"])).ReadAsArray().astype(float)
        m1, m2 = ndimage.uniform_filter(ortho, 19), ndimage.uniform_filter(ortho * ortho, 19)
        flat = np.sqrt(np.maximum(m2 - m1 * m1, 0.0)) < LOW_CONTRAST_DN
        land = np.where(np.isin(land, (BARE, CROPS)) & flat, LOW_TEXTURE, land)
        # building outlines on the class grid (same grid as the DSM / DTM rasters)
        glon, glat = gt[0] + (np.arange(land.shape[1]) + 0.5) * gt[1], gt[3] + (np.arange(land.shape[0]) + 0.5) * gt[5]
        glon, glat = np.meshgrid(glon, glat)
        building = (land == CITY) & (self.dsm.height(glon, glat) - dtm.height(glon, glat) > BUILDING_M)
        outline = building ^ ndimage.binary_erosion(building)
        me, mn = metres_per_degree(gt[3])
        dist = ndimage.distance_transform_edt(~outline, sampling=(abs(gt[5]) * mn, gt[1] * me))
        i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, land.shape[0] - 1)
        j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, land.shape[1] - 1)
        self.cls = land[i, j]
        self.edge = dist[i, j] <= EDGE_M
        other = ndimage.distance_transform_edt(
            ~np.isin(land, (FOREST, CITY, WATER)), sampling=(abs(gt[5]) * mn, gt[1] * me)
        )
        self.near = np.isin(self.cls, (BARE, CROPS, LOW_TEXTURE)) & (other[i, j] <= EDGE_M)
        self.water = self.cls == WATER
        self.buildings = int(ndimage.label(building)[1])

    def dem(self, mp):
        """The 10 m DEM of MultiPoints `mp` (module docstring) sampled at the evaluation cells (NaN: gap)."""
        obs = mp.observations
        res = intersection.intersect(
            self.models,
            intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]),
            h0=float(np.mean(self.h)),
        )
        ok = res.ok
        dem = interpolate_dem(
            PointSet(res.lon[ok], res.lat[ok], res.h[ok], wgs84()),
            DemParams(cell=CELL, crs=self.srs, max_edge=MAX_EDGE_M),
        )
        u, v = dem.grid.to_cells(self.x, self.y)
        i, j = np.round(v).astype(int), np.round(u).astype(int)
        inside = (i >= 0) & (i < dem.grid.rows) & (j >= 0) & (j < dem.grid.cols)
        out = np.full(len(self.x), np.nan)
        out[inside] = dem.heights[i[inside], j[inside]]
        return out

    def table(self, dh, common):
        """{class name: (cells, coverage, RMS, NMAD, MAE, RMS over the `common` cells)} of DEM -
        truth `dh` (NaN: gap), the classes and the building-edge zone."""
        rows = {}
        zones = {name: self.cls == c for c, name in CLASSES.items()}
        zones["bldg edge"] = self.edge
        zones[NEAR] = self.near
        for name, k in zones.items():
            d = dh[k][np.isfinite(dh[k])]
            med = np.median(d) if d.size else np.nan
            rows[name] = (
                int(k.sum()),
                float(np.isfinite(dh[k]).mean()) if k.any() else np.nan,
                float(np.sqrt(np.mean(d**2))) if d.size else np.nan,
                float(1.4826 * np.median(np.abs(d - med))) if d.size else np.nan,
                float(np.mean(np.abs(d))) if d.size else np.nan,
                float(np.sqrt(np.mean(dh[k & common] ** 2))) if (k & common).any() else np.nan,
            )
        return rows


def compare(truth, strategies):
    """{label: Truth.table} of {label: MultiPoints}, 'common' = the cells every DEM defines."""
    dh = {label: truth.dem(mp) - truth.h for label, mp in strategies.items()}
    common = np.all([np.isfinite(d) for d in dh.values()], axis=0)
    return {label: truth.table(d, common) for label, d in dh.items()}


def format_tables(tables):
    """Side-by-side text of {label: Truth.table(...)} (heights in m)."""
    labels = list(tables)
    head = f"{'class':10} {'cells':>6} " + " ".join(f"{lab[:14]:>14} cov    RMS   NMAD    MAE RMScom" for lab in labels)
    lines = [head]
    for name in tables[labels[0]]:
        n = tables[labels[0]][name][0]
        cols = " ".join(
            f"{' ':>14} {100 * t[name][1]:3.0f}% " + " ".join(f"{v:6.2f}" for v in t[name][2:]) for t in tables.values()
        )
        lines.append(f"{name:10} {n:6d} {cols}")
    return "\n".join(lines)
