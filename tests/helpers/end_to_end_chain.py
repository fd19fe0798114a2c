"""The whole chain of issue 5 on a simulated SPOT 5 triplet, run once for test_end_to_end.py:
match, select tie points, adjust from 19 control points (the rest check) with the automatic
parameter selection, intersect the mass points, interpolate the 10 m DEM, orthorectify the HRG
image on the adjusted model and that DEM, and assess points and DEM against the true DSM and DTM
per class. Twice: with the three images (HRG, HRS1, HRS2) and with HRS1 + HRS2 alone
(matched as a pair, adjusted from the same control points), the "2 images only" of Kornus et al. (2006, sections
3.6-3.7).

Classes (a class raster on classes.tif's grid): the simulator's land cover with the open classes
(bare fields, grass/crops) split by the texture an area matcher sees: where the standard deviation
of the true orthoimage over a 19-cell (95 m, one HRG template) window is below
matching_scene.LOW_CONTRAST_DN they are "low-texture fields". A second raster marks the textured
open cells at least EDGE_M from forest, city and water ("interior"): nearer, an HRG template also
covers tree crowns, roofs or the lake, and the matched height is no longer that of the field.

The result holds the class rasters' paths, not ClassRaster objects: a gdal.Dataset still alive when
pytest-qgis's session fixture calls QgsApplication.exitQgis() segfaults when it is freed (a module
fixture's value outlives the last test's teardown when this module runs last)."""

import time

import numpy as np
from osgeo import gdal
from scipy import ndimage

from pushbroom.algorithms import sensors
from pushbroom.algorithms.adjustment.bundle import check_points
from pushbroom.algorithms.adjustment.observations import Observations, tie_observations
from pushbroom.algorithms.adjustment.selection import select_parameters
from pushbroom.algorithms.atomic import work_dir
from pushbroom.algorithms.crs import srs
from pushbroom.algorithms.dem_store import read_dem, store_dem
from pushbroom.algorithms.execution import Execution
from pushbroom.algorithms.geodesy import metres_per_degree
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing_strategy import RegionGrowing, RegionGrowingSettings
from pushbroom.algorithms.matching.stereo_set import StereoSet
from pushbroom.algorithms.matching.tiepoints import select_tie_points
from pushbroom.algorithms.matching.tiled_rounds import match_in_memory
from pushbroom.algorithms.ortho import OutputGrid, orthorectify
from pushbroom.algorithms.quality.assessment import Labelling, assess
from pushbroom.algorithms.quality.classes import ClassRaster
from pushbroom.algorithms.quality.height_differences import Reference
from pushbroom.algorithms.simulation.terrain import BARE, CITY, CROPS, FOREST, WATER
from pushbroom.algorithms.surface import intersection, pointcloud
from pushbroom.algorithms.surface.point_input import read_points
from pushbroom.algorithms.surface.tin_dem import DemParams, interpolate_dem, write_dem
from tests.helpers.adjustment_scene import IDS, LABELS, NAMES, point_observations
from tests.helpers.matching_scene import LOW_CONTRAST_DN

RUNS = {"three images": NAMES, "HRS only": NAMES[1:]}
N_CONTROL = 19
DEM_CELL = 10.0
#: px of HRG between region growing's neighbours: the pipeline model's default (build_pipeline_model.py); the
#: 10 m DEM on textured open ground, RMS vs the true DSM (textured open / interior, m): STEP 10 (Heipke et al.'s
#: value)
#: 3.85 / 1.76, 5 2.75 / 1.29, 3 2.53 / 1.19 (test_end_to_end.py; the last with a prototype of the
#: support weights whose grey-level scale was a fixed 30 DN); about 5 x and 10 x the matching time of STEP 10
STEP = 5
LOW_TEXTURE = 6  # class code of the open classes' low-texture cells
TEXTURE_CLASSES = {
    WATER: "water",
    BARE: "bare fields",
    CROPS: "grass/crops",
    LOW_TEXTURE: "low-texture fields",
    FOREST: "forest",
    CITY: "city/buildings",
}
TEXTURED_OPEN = (BARE, CROPS)
TEMPLATE_CELLS = 19  # 95 m: a 19 px HRG template on the 5 m ground grid
EDGE_M = 50.0  # half an HRG template (47.5 m), rounded up
INTERIOR = 1  # class code of the interior raster


def _write_classes(like, out, values, names):
    """Byte raster `out` on the grid of dataset `like` with class names in CLASS_<n> metadata."""
    dst = gdal.GetDriverByName("GTiff").Create(str(out), like.RasterXSize, like.RasterYSize, 1, gdal.GDT_Byte)
    dst.SetGeoTransform(like.GetGeoTransform())
    dst.SetProjection(like.GetProjection())
    dst.SetMetadata({f"CLASS_{k}": v for k, v in names.items()})
    dst.GetRasterBand(1).WriteArray(values.astype(np.uint8))
    dst = None
    return out


def field_edge_distance(land, geotransform):
    """Distance (m) of each cell of the texture-class raster `land` (north-up lon/lat grid) from the
    nearest cell of forest, city or water (0 on those)."""
    _, dlon, _, lat0, _, dlat = geotransform
    me, mn = metres_per_degree(lat0 + 0.5 * land.shape[0] * dlat)
    return ndimage.distance_transform_edt(
        np.isin(land, TEXTURED_OPEN + (LOW_TEXTURE,)), sampling=(abs(dlat) * mn, dlon * me)
    )


def class_rasters(paths, folder):
    """Paths of the (texture classes, interior) rasters (module docstring)."""
    ds = gdal.Open(str(paths["classes"]))
    land = ds.ReadAsArray()
    ortho = gdal.Open(str(paths["orthoimage"])).ReadAsArray().astype(float)
    m1, m2 = ndimage.uniform_filter(ortho, TEMPLATE_CELLS), ndimage.uniform_filter(ortho * ortho, TEMPLATE_CELLS)
    flat = np.sqrt(np.maximum(m2 - m1 * m1, 0.0)) < LOW_CONTRAST_DN
    land = np.where(np.isin(land, TEXTURED_OPEN) & flat, LOW_TEXTURE, land)
    interior = np.isin(land, TEXTURED_OPEN) & (field_edge_distance(land, ds.GetGeoTransform()) >= EDGE_M)
    return (
        _write_classes(ds, folder / "classes.tif", land, TEXTURE_CLASSES),
        _write_classes(
            ds,
            folder / "interior.tif",
            interior * INTERIOR,
            {INTERIOR: f"textured open, >= {EDGE_M:g} m from forest, city, water"},
        ),
    )


def surface(models, mass, h0, folder, name):
    """Intersect the mass points with `models`; write the point cloud (LAS, UTM; field group as
    matched) and the 10 m DEM. Returns (Intersection, LAS path, DEM path, DemResult)."""
    obs = mass.observations
    result = intersection.intersect(
        models, intersection.Measurements(obs["image_id"], obs["point_id"], obs["col"], obs["row"]), h0=h0
    )
    pos = np.searchsorted(mass.points["id"], result.point)
    ok = result.ok
    fields = pointcloud.cloud_fields(result, group=mass.points["group"][pos], rho=mass.points["rho_min"][pos])
    las, _, _ = pointcloud.write_point_cloud(
        folder / f"{name}.las", result.lon[ok], result.lat[ok], result.h[ok], fields
    )
    dem = interpolate_dem(read_points(las), DemParams(cell=DEM_CELL))
    dem_path = folder / f"{name}_dem.tif"
    write_dem(dem, dem_path)
    return result, las, dem_path, dem


def adjust(paths, names, mass, h0):
    """select_parameters on the supplied models of `names` from the control points measured in
    those images and the tie points selected from `mass`; (models, Selection, check_points)."""
    models = {IDS[n]: sensors.load(paths["images"][n]["metadata"]) for n in names}
    control = point_observations(paths["points"], IDS, N_CONTROL)
    control = Observations(
        control.points, control.measurements[np.isin(control.measurements["image_id"], list(models))]
    )
    obs = control.concatenate(tie_observations(select_tie_points(mass, cell=100.0)))
    selection = select_parameters(models, obs, names=LABELS, height=h0)
    return models, selection, check_points(selection.result, obs, height=h0)


def run_chain(paths, folder, workers=2):
    """Everything the tests read (module docstring) from the simulate_scene `paths`, with the time of each
    step (s); outputs in `folder`."""
    times = {}
    clock = [time.perf_counter()]

    def lap(step):
        now = time.perf_counter()
        times[step], clock[0] = now - clock[0], now

    lo, hi = read_dem(paths["dsm"]).height_range
    h0 = 0.5 * (lo + hi)
    classes, interior = class_rasters(paths, folder)
    out = {"paths": paths, "times": times, "classes": classes, "interior": interior}
    for label, names in RUNS.items():
        supplied = [sensors.load(paths["images"][n]["metadata"]) for n in names]
        stereo = StereoSet.of(
            [paths["images"][n]["imagery"] for n in names],
            supplied,
            names,
            [IDS[n] for n in names],
            (lo - 100.0, hi + 100.0),
        )
        mass = match_in_memory(
            RegionGrowing,
            stereo,
            RegionGrowingSettings(grow=GrowParams(step=STEP, support_weights=True)),
            Execution("threads", workers),
        )
        lap(f"match {label}")
        models, selection, check = adjust(paths, names, mass, h0)
        lap(f"adjust {label}")
        result, las, dem_path, dem = surface(models, mass, h0, folder, label.replace(" ", "_"))
        lap(f"intersect + DEM {label}")
        out[label] = {
            "mass": mass,
            "models": models,
            "selection": selection,
            "check": check,
            "intersection": result,
            "las": las,
            "dem_path": dem_path,
            "dem": dem,
            **{
                ref: assess(
                    Reference(paths[ref]), points=las, dem=dem_path, labelling=Labelling(classes=ClassRaster(classes))
                )
                for ref in ("dsm", "dtm")
            },
        }
        lap(f"assess {label}")
    truth = gdal.Open(str(paths["orthoimage"]))
    grid = OutputGrid(srs(4326), truth.GetGeoTransform(), truth.RasterXSize, truth.RasterYSize)
    with work_dir(folder / "hrg_ortho.tif", "the stored DEM") as stored:
        out["ortho"] = orthorectify(
            paths["images"]["HRG"]["imagery"],
            out["three images"]["models"][IDS["HRG"]],
            store_dem(out["three images"]["dem_path"], stored),
            folder / "hrg_ortho.tif",
            grid=grid,
            execution=Execution("threads", workers),
        )
    lap("orthorectify")
    return out
