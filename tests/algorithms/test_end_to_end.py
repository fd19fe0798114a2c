"""End to end on a simulated SPOT 5 triplet (end_to_end_chain.py): from the supplied (perturbed, ~25 m)
orientation, 19 control points and region-growing mass points to object points, a 10 m DEM and the HRG
orthoimage, assessed against the simulator's truth; and the same from HRS1 + HRS2 alone.

Scene: 12 km instead of the default 20 km, centred at 84.2011 W 36.5543 N, with the land cover mix of
the 20 km scene and more lake (the low-texture class under test). The chain runs at STEP 5
(end_to_end_chain.STEP) with MPGC's support weights (refinement.py), as the pipeline model.

The orthoimage meets its target (ORTHO_TARGET). The point and DEM height targets (POINT_TARGET,
DEM_TARGET) are not met: the bounds (*_BOUND) sit just above the measured values. On textured open
ground the error is the matched surface, not the orientation: the templates reach into forest, city and
water beside the fields, and at this spacing the TIN's ramps between field and canopy points alone exceed
the DEM target; in the fields' interior it is the matcher's along-track error through the HRS1-HRS2
base. Figures and their breakdown: docs/validation.md#end-to-end."""

import numpy as np
import pytest
from osgeo import gdal
from scipy import ndimage
from scipy.spatial import Delaunay

from pushbroom.algorithms import sensors
from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dem import Dem
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.quality.assessment import Labelling, assess, labels
from pushbroom.algorithms.quality.classes import ClassRaster
from pushbroom.algorithms.quality.height_differences import Reference
from pushbroom.algorithms.quality.statistics import summarize
from pushbroom.algorithms.simulation import SceneConfig
from pushbroom.algorithms.simulation.terrain import BARE, CROPS, WATER
from pushbroom.algorithms.surface import intersection
from pushbroom.algorithms.surface.point_input import PointSet, read_points
from pushbroom.algorithms.surface.tin_dem import DemParams, interpolate_dem, write_dem
from tests.helpers.adjustment_scene import IDS
from tests.helpers.end_to_end_chain import (
    DEM_CELL,
    INTERIOR,
    LOW_TEXTURE,
    TEMPLATE_CELLS,
    TEXTURE_CLASSES,
    TEXTURED_OPEN,
    field_edge_distance,
    run_chain,
)
from tests.helpers.ortho_oracle import geometric_error

pytestmark = pytest.mark.slow

CONFIG = SceneConfig(size_km=12.0, points=30, centre_lon=-84.2011, centre_lat=36.5543)
POINT_TARGET = 0.7  # m, RMS of 3-ray points vs the true DSM on textured open classes
POINT_BOUND = (2.4, 1.25)  # m, textured open / interior: target not met (docs/validation.md#end-to-end)
DEM_TARGET = 1.0  # m, RMS of the 10 m DEM there
DEM_BOUND = (2.9, 1.4)  # m, textured open / interior: target not met (docs/validation.md#end-to-end)
ORTHO_TARGET = 0.3  # px, geometric error of the HRG orthoimage on open classes
BLUNDER = 5.0  # m: |dh| beyond this is a blunder
OPEN, INNER = "textured open", "  interior"


@pytest.fixture(scope="module")
def chain(simulated, tmp_path_factory):
    return run_chain(simulated(CONFIG), tmp_path_factory.mktemp("end_to_end"))


def rows(chain, assessed, select=None):
    """{label: Stats} of the dh of `assessed` (where `select`) per class, then the textured open classes
    together and their interior (end_to_end_chain)."""
    dh, classes = assessed.differences.dh, assessed.classes
    inner = labels(ClassRaster(chain["interior"]), assessed.differences) == INTERIOR
    if select is not None:
        dh, classes, inner = dh[select], classes[select], inner[select]
    out = {name: summarize(dh[classes == c]) for c, name in TEXTURE_CLASSES.items() if np.any(classes == c)}
    return {**out, OPEN: summarize(dh[np.isin(classes, TEXTURED_OPEN)]), INNER: summarize(dh[inner])}


def report_table(figures, title, table):
    """Report a {label: Stats} table; returns it."""
    figures.table(
        title,
        [
            {
                "class": label.strip(),
                "N": s.n,
                "mean": s.mean,
                "RMS": s.rms,
                "sigma": s.sigma,
                "NMAD": s.nmad,
                "<2 m %": s.shares[0],
                "2-5 m %": s.shares[1],
                ">5 m %": s.shares[2],
            }
            for label, s in table.items()
        ],
    )
    return table


def point_tables(chain, run, reference, figures):
    """{group: table} of the object points of `run` against `reference` ('dsm' / 'dtm'): group 3 and >= 2
    (three images), all two-ray points (HRS only)."""
    points = chain[run][reference][0]
    groups = ((3, "3 (3 rays)"), (2, ">= 2")) if run == "three images" else ((1, "1 (2 rays)"),)
    return {
        g: report_table(
            figures,
            f"{run}: object points of group {text} vs the true {reference.upper()} (m)",
            rows(chain, points, points.differences.group >= g),
        )
        for g, text in groups
    }


def dem_table(chain, run, reference, figures):
    return report_table(
        figures, f"{run}: 10 m DEM vs the true {reference.upper()} (m)", rows(chain, chain[run][reference][1])
    )


def group3_open(assessed):
    """Mask of the group-3 points of an Assessed point cloud on the textured open classes."""
    return np.isin(assessed.classes, TEXTURED_OPEN) & (assessed.differences.group >= 3)


def test_adjustment_check_points(chain, figures):
    """The orientation the surface rests on: check point RMS with three images and with HRS only
    (Kornus et al. 2006, Table 3, real data: 2.7 / 2.3 / 1.9 m and 3.8 / 2.9 / 2.1 m); without the HRG the planimetric
    error grows."""
    planimetric = {}
    for run in ("three images", "HRS only"):
        check = chain[run]["check"]
        rms = np.array([np.sqrt(np.mean(check[k] ** 2)) for k in ("dE", "dN", "dH")])
        theory = np.sqrt(np.mean(check["sigma"] ** 2, axis=0))
        figures.report(f"{run}: selected free coefficients", chain[run]["selection"].free)
        figures.report(f"{run}: check points", len(check["dE"]))
        figures.report(f"{run}: check point RMS E, N, H", rms, "m")
        figures.report(f"{run}: theoretical RMS E, N, H", theory, "m")
        assert len(check["dE"]) >= 8
        assert np.all(rms < 2.0 * theory)
        planimetric[run] = np.hypot(*rms[:2])
    figures.report("times", chain["times"], "s")
    assert planimetric["HRS only"] > planimetric["three images"]


@pytest.mark.ratchet
def test_object_points_against_the_true_dsm_and_dtm(chain, figures):
    """Issue target: 3-ray (group 3) points, RMS vs the true DSM <= 0.7 m on textured open classes: not met
    (module docstring)."""
    dsm = point_tables(chain, "three images", "dsm", figures)
    point_tables(chain, "three images", "dtm", figures)
    measured = dsm[3]
    figures.report(f"group 3, {OPEN}: RMS", measured[OPEN].rms, "m", f"target <= {POINT_TARGET} m")
    figures.report("group 3, interior: RMS", measured[INNER].rms, "m", f"target <= {POINT_TARGET} m")
    # the assessment's dh are the intersected heights minus the DSM at the points (LAS and assess round trip)
    r = chain["three images"]["intersection"]
    direct = r.h[r.ok] - read_dem(chain["paths"]["dsm"]).height(r.lon[r.ok], r.lat[r.ok])
    assert abs(summarize(direct).rms - summarize(chain["three images"]["dsm"][0].differences.dh).rms) < 0.01
    assert measured[OPEN].n > 5000 and measured[INNER].n > 1000
    assert measured[OPEN].rms <= POINT_BOUND[0] and measured[INNER].rms <= POINT_BOUND[1]
    # the relief a uniform 95 m window cannot resolve: the true DSM minus its template mean (the plane
    # fit's height at the centre), on the textured open and the interior cells of the DSM's grid
    z = gdal.Open(str(chain["paths"]["dsm"])).ReadAsArray().astype(float)
    rough = z - ndimage.uniform_filter(z, TEMPLATE_CELLS)
    cls, inner = (gdal.Open(str(chain[k])).ReadAsArray() for k in ("classes", "interior"))
    assert cls.shape == inner.shape == z.shape
    floor = [float(np.sqrt(np.mean(rough[m] ** 2))) for m in (np.isin(cls, TEXTURED_OPEN), inner == INTERIOR)]
    figures.report(
        f"relief inside a uniform {TEMPLATE_CELLS}-cell window (DSM minus its window mean), {OPEN}: RMS", floor[0], "m"
    )
    figures.report(f"relief inside a uniform {TEMPLATE_CELLS}-cell window, interior: RMS", floor[1], "m")
    # where the squared error is: by the points' distance from forest, city and water
    assessed = chain["three images"]["dsm"][0]
    d, group3 = assessed.differences, group3_open(assessed)
    gt = gdal.Open(str(chain["classes"])).GetGeoTransform()
    edge = Dem(field_edge_distance(cls, gt), gt).height(*reproject(d.x[group3], d.y[group3], d.srs, wgs84()))
    dh = d.dh[group3]
    share, by_distance = {}, []
    for lo, hi in ((0, 10), (10, 20), (20, 50), (50, 100), (100, np.inf)):
        m = (edge >= lo) & (edge < hi)
        share[lo] = np.sum(dh[m] ** 2) / np.sum(dh**2)
        by_distance.append(
            {
                "m": f"{lo:g}-{hi:g}",
                "N": m.sum(),
                "share %": 100 * m.mean(),
                "mean": dh[m].mean(),
                "RMS": np.sqrt(np.mean(dh[m] ** 2)),
                "of dh^2 %": 100 * share[lo],
            }
        )
    figures.table(f"group 3, {OPEN}, by distance from forest, city, water (m)", by_distance)
    assert share[0] > 0.5 and share[50] + share[100] < 0.1


@pytest.mark.ratchet
def test_group3_height_error_is_the_matched_surface_not_the_orientation(chain, figures):
    """Where the group-3 height error comes from: the points intersected again with the truth models
    (the matching's error alone) and with the adjusted models at the exact image positions (the HRG
    template centre's ray meets the true DSM, projected into HRS1 and HRS2 by their truth models: the
    orientation's error alone). The matching's error dominates; on fields it is deterministic, not the
    image noise (aliasing of the HRS images and the relief inside the template): docs/validation.md#end-to-end."""
    mass, models, paths = chain["three images"]["mass"], chain["three images"]["models"], chain["paths"]
    truth = {IDS[name]: sensors.load(path) for name, path in paths["truth_metadata"].items()}
    dsm = read_dem(paths["dsm"])
    ids = mass.points["id"][mass.points["group"] == 3]
    obs = mass.observations[np.isin(mass.observations["point_id"], ids)]
    matched = {}
    for image in truth:
        o = obs[obs["image_id"] == image]
        o = o[np.argsort(o["point_id"])]
        assert np.array_equal(o["point_id"], ids)
        matched[image] = (o["col"], o["row"])
    lon, lat, h = truth[IDS["HRG"]].image_to_dem(*matched[IDS["HRG"]], dsm)
    exact = {
        image: matched[image] if image == IDS["HRG"] else truth[image].ground_to_image(lon, lat, h) for image in truth
    }
    classes, interior = (ClassRaster(chain[k]).at_points(lon, lat, wgs84()) for k in ("classes", "interior"))
    where = {OPEN: np.isin(classes, TEXTURED_OPEN), INNER: interior == INTERIOR}

    def dh(models_, positions):
        image = np.repeat(list(positions), len(ids))
        col, row = (np.concatenate([positions[k][c] for k in positions]) for c in (0, 1))
        r = intersection.intersect(
            models_, intersection.Measurements(image, np.tile(ids, len(positions)), col, row), h0=float(np.mean(h))
        )
        out = np.full(len(ids), np.nan)
        pos = np.searchsorted(ids, r.point[r.ok])
        out[pos] = r.h[r.ok] - dsm.height(r.lon[r.ok], r.lat[r.ok])
        return out

    parts = {
        "adjusted models, matched": dh(models, matched),
        "truth models, matched (matching)": dh(truth, matched),
        "adjusted models, exact (orientation)": dh(models, exact),
        "truth models, exact": dh(truth, exact),
    }
    stats = {}
    for label, values in parts.items():
        stats[label] = {k: summarize(values[m & np.isfinite(values)]) for k, m in where.items()}
    figures.table(
        "group 3 height error vs the true DSM (m)",
        [
            {
                "": label,
                **{f"{k.strip()} {q}": getattr(s, q.lower()) for k, s in by_class.items() for q in ("RMS", "mean")},
            }
            for label, by_class in stats.items()
        ],
    )
    for k, m in where.items():
        figures.report(
            f"{k.strip()}: along-track (row) matching error RMS HRS1, HRS2",
            [np.sqrt(np.mean((matched[IDS[n]][1] - exact[IDS[n]][1])[m] ** 2)) for n in ("HRS1", "HRS2")],
            "px",
        )
    assert stats["truth models, exact"][INNER].rms < 0.01 and stats["truth models, exact"][OPEN].rms < 0.01
    assessed = chain["three images"]["dsm"][0]  # the same points, classed where they were intersected
    assert (
        abs(stats["adjusted models, matched"][OPEN].rms - summarize(assessed.differences.dh[group3_open(assessed)]).rms)
        < 0.05
    )
    matching, orientation = stats["truth models, matched (matching)"], stats["adjusted models, exact (orientation)"]
    assert orientation[INNER].rms < 0.5 and matching[INNER].rms > 2.0 * orientation[INNER].rms
    assert orientation[OPEN].rms < 0.5 and matching[OPEN].rms > 4.0 * orientation[OPEN].rms


@pytest.mark.ratchet
def test_dem_against_the_true_dsm_and_dtm(chain, tmp_path, figures):
    """Issue target: the 10 m DEM, RMS vs the true DSM <= 1.0 m on textured open classes: not met (module
    docstring). Beside it the same DEM step on the same point positions with the true DSM's heights: the
    part of the error that the points' spacing and the TIN's ramps make whatever the matcher measures.
    Figures: docs/validation.md#end-to-end."""
    dsm = dem_table(chain, "three images", "dsm", figures)
    dem_table(chain, "three images", "dtm", figures)
    figures.report(f"DEM, {OPEN}: RMS", dsm[OPEN].rms, "m", f"target <= {DEM_TARGET} m")
    figures.report("DEM, interior: RMS", dsm[INNER].rms, "m", f"target <= {DEM_TARGET} m")
    cloud = read_points(chain["three images"]["las"])
    lon, lat = reproject(cloud.x, cloud.y, cloud.srs, wgs84())
    exact = PointSet(cloud.x, cloud.y, read_dem(chain["paths"]["dsm"]).height(lon, lat), cloud.srs)
    write_dem(interpolate_dem(exact, DemParams(cell=DEM_CELL)), tmp_path / "exact_heights_dem.tif")
    floor = rows(
        chain,
        assess(
            Reference(chain["paths"]["dsm"]),
            dem=tmp_path / "exact_heights_dem.tif",
            labelling=Labelling(classes=ClassRaster(chain["classes"])),
        )[0],
    )
    figures.report(f"DEM of the same points with their true heights, {OPEN}: RMS", floor[OPEN].rms, "m")
    figures.report("DEM of the same points with their true heights, interior: RMS", floor[INNER].rms, "m")
    assert dsm[OPEN].n > 10000 and floor[OPEN].n > 0.9 * dsm[OPEN].n
    assert dsm[OPEN].rms <= DEM_BOUND[0] and dsm[INNER].rms <= DEM_BOUND[1]
    # interior: the matched heights' error dominates; all textured open cells: the ramps between field and
    # canopy or roof points alone exceed the target (the matched heights, smoothed over the template, less so)
    assert floor[INNER].rms < dsm[INNER].rms and floor[OPEN].rms > DEM_TARGET


def test_low_texture_areas_are_gaps_not_blunders(chain, figures):
    """Water and low-texture fields are gaps: few points and DEM cells (the matcher fails there and the
    DEM leaves triangles longer than MAX_EDGE open); not blunders: the points there are no worse (within
    20 %) than on the textured open classes (share of |dh| > 5 m vs the true DSM; the shore and field
    edges give both their large dh) and DEM blunders cover under 1 % of their area. Areas: the DEM
    grid's cells inside the points' convex hull."""
    points, dem = chain["three images"]["dsm"]
    d = dem.differences
    grid_classes = ClassRaster(chain["classes"]).on_grid(d.grid)
    x, y = d.grid.centres()
    hull = Delaunay(np.column_stack([points.differences.x, points.differences.y]))
    inside = (hull.find_simplex(np.column_stack([x.ravel(), y.ravel()])) >= 0).reshape(grid_classes.shape)
    cell_km2 = abs(d.grid.geotransform[1] * d.grid.geotransform[5]) * 1e-6
    found, table = {}, []
    for c, name in TEXTURE_CLASSES.items():
        area = inside & (grid_classes == c)
        density = np.sum(points.classes == c) / (area.sum() * cell_km2)
        cover = np.mean(np.isfinite(d.grid.values[area]))
        blunders = [np.mean(np.abs(a.differences.dh[a.classes == c]) > BLUNDER) for a in (points, dem)]
        found[c] = (density, cover, blunders[0], cover * blunders[1])
        table.append(
            {
                "class": name,
                "km2": area.sum() * cell_km2,
                "points/km2": density,
                "DEM cover %": 100 * cover,
                "points |dh|>5m %": 100 * blunders[0],
                "DEM |dh|>5m %": 100 * blunders[1],
                "area w/ DEM blunder %": 100 * cover * blunders[1],
            }
        )
    figures.table("per class", table)
    open_density, open_cover, open_blunders, _ = np.mean([found[c] for c in TEXTURED_OPEN], axis=0)
    for c in (WATER, LOW_TEXTURE):
        density, cover, point_blunders, blunder_area = found[c]
        assert density < 0.2 * open_density and cover < 0.2 * open_cover  # gaps
        assert point_blunders < 1.2 * open_blunders and blunder_area < 0.01  # not blunders


def test_hrs_only_against_three_images(chain, figures):
    """Kornus et al. 2006, section 3.6-3.7: HRS1 + HRS2 matched as a pair, adjusted from the same control
    points, against the three images, per class vs the true DTM (the papers' case) and DSM. The nadir HRG adds
    no height precision to HRS1 + HRS2 (a third ray at the mean of the other two's viewing angles), but its
    third combination confirms the points: on the interior of the fields HRS-only points and DEM
    are worse (Kornus et al. 2006 on real data: 10 % (flat) to 60 % (mountains) for the DEM). Over all textured open
    cells HRS only is better: the pair matches a tenth of the forest points, so fewer canopy heights
    reach the field edges (through the templates and the DEM's triangles)."""
    tables = {}
    for reference in ("dtm", "dsm"):
        for run in ("three images", "HRS only"):
            tables[run, reference] = (
                point_tables(chain, run, reference, figures),
                dem_table(chain, run, reference, figures),
            )
    three, hrs = tables["three images", "dtm"], tables["HRS only", "dtm"]
    pairs = {
        f"points, {OPEN} (group 3 / 2 rays)": (three[0][3][OPEN], hrs[0][1][OPEN]),
        "points, interior": (three[0][3][INNER], hrs[0][1][INNER]),
        f"DEM, {OPEN}": (three[1][OPEN], hrs[1][OPEN]),
        "DEM, interior": (three[1][INNER], hrs[1][INNER]),
    }
    figures.table(
        "vs the true DTM, RMS (m)",
        [
            {
                "": label,
                "three images": a.rms,
                "HRS only": b.rms,
                "HRS only - three images %": 100 * (b.rms / a.rms - 1),
            }
            for label, (a, b) in pairs.items()
        ],
    )
    assert pairs["points, interior"][1].rms > pairs["points, interior"][0].rms
    assert pairs["DEM, interior"][1].rms > pairs["DEM, interior"][0].rms


@pytest.mark.ratchet
def test_orthoimage_geometric_error(chain, figures):
    """Issue target: HRG orthoimage on the adjusted model and the produced DEM, geometric error vs the
    true orthoimage below 0.3 px on open classes."""
    shifts = geometric_error(chain["paths"], chain["ortho"].path, (BARE, CROPS))
    rms = float(np.sqrt(np.mean(np.sum(shifts**2, axis=1))))
    mean = shifts.mean(axis=0)
    figures.report("patches in the open classes", len(shifts))
    figures.report("shift against the true orthoimage, RMS", rms, "px", f"target < {ORTHO_TARGET} px")
    figures.report("shift against the true orthoimage, mean", mean, "px")
    figures.report("orthoimage", chain["ortho"].summary())
    assert len(shifts) > 1000
    assert rms < ORTHO_TARGET
