"""Which position should a dense point trust, LSM's or the semi-global one, and can LSM's own residual tell?

On the 3 km simulated SPOT 5 triplet (HRG, HRS1, HRS2; the supplied models, the DSM's height range +- 100 m),
dense matching (default DenseParams but 256 px tiles) twice: with the refinement (LSM's positions where it
accepts them) and without it (every position the semi-global one); every point intersected with the TRUE models
(the error is the matching's alone). Then 10 m per-cell DSMs (cell_dem.cells_on_grid, k 3, RADIUS 1, tiers as the
DEM step's; the semi-global points all count as measured) against the true DSM at the cell centres, by class
(tests/helpers/dsm_comparison.py), where a point takes its semi-global position instead of LSM's:
- nowhere (the product), everywhere;
- by its true class (an oracle: the bound of any rule);
- where LSM's template residual is too large for one surface: q = s_t sqrt(1 - rho^2) / sigma_n > Q, with s_t the
  standard deviation of HRG's 19 px template at the node, rho the point's smaller LSM correlation (so
  s_t sqrt(1 - rho^2) is the RMS residual of the template after LSM's radiometric fit) and sigma_n HRG's noise
  (the robust form of Immerkaer's estimator: 1.4826 MAD of the image convolved with [[1,-2,1],[-2,4,-2],[1,-2,1]],
  over 6). One surface under an affine leaves about the noise (q ~ 1); a template across several heights leaves
  more. The variance factor's test of the least-squares fit (Foerstner's), per node.

Reference: J. Immerkaer, "Fast noise variance estimation", Computer Vision and Image Understanding 64(2), 1996."""

import tempfile

import numpy as np
from osgeo import gdal
from scipy import ndimage
from scipy.spatial import cKDTree

from pushbroom.algorithms.crs import reproject, wgs84
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.simulation.terrain import CITY, FOREST
from pushbroom.algorithms.surface.cell_dem import (
    CellSettings,
    cells_on_grid,
    point_tiers,
)
from studies.sim_dense import BEFORE, evaluation_grid, rms, truth_cloud
from tests.helpers.dsm_comparison import CLASSES, Truth

THRESHOLDS = (1.5, 2.0, 3.0, 4.0)
LAPLACE = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], float)


def noise_sigma(image: np.ndarray) -> float:
    """The image's noise (DN): the robust form of Immerkaer's estimator (module docstring)."""
    laplace = ndimage.convolve(image, LAPLACE)[1:-1, 1:-1]
    return float(1.4826 * np.median(np.abs(laplace - np.median(laplace))) / 6.0)


def residual_q(image: np.ndarray, col: np.ndarray, row: np.ndarray, rho: np.ndarray, sigma_n: float) -> np.ndarray:
    """q = s_t sqrt(1 - rho^2) / sigma_n at the image positions (col, row) (module docstring; s_t over the 19 px
    window of `image` around each position's pixel); NaN where rho is."""
    mean = ndimage.uniform_filter(image, 19)
    s_t = np.sqrt(np.maximum(ndimage.uniform_filter(image * image, 19) - mean * mean, 0.0))
    r = np.clip(np.floor(row).astype(int), 0, image.shape[0] - 1)
    c = np.clip(np.floor(col).astype(int), 0, image.shape[1] - 1)
    return s_t[r, c] * np.sqrt(np.maximum(1.0 - np.asarray(rho, float) ** 2, 0.0)) / sigma_n


def dense(paths, truth, lsm):
    """Per point of the dense matching (refinement `lsm`): id, ok, x, y, z, rays, rho_min, HRG col/row."""
    cloud = truth_cloud(paths, truth, DenseParams(tile=256, lsm=lsm, **BEFORE))
    res, obs = cloud.result, cloud.points.observations
    x, y = reproject(res.lon, res.lat, wgs84(), truth.srs)
    ref = obs[obs["image_id"] == 1]
    ref = ref[np.searchsorted(ref["point_id"], res.point)]
    rho = cloud.rho() if lsm else np.zeros(res.point.size)
    tier = point_tiers(rho, res.rays)
    return {
        "id": res.point,
        "ok": res.ok,
        "x": x,
        "y": y,
        "z": res.h,
        "tier": tier,
        "rho": rho,
        "col": ref["col"],
        "row": ref["row"],
    }


def main():
    paths = simulate_scene(SceneConfig.small(), tempfile.mkdtemp() + "/scene")
    truth = Truth(paths)
    lsm, sgm = dense(paths, truth, True), dense(paths, truth, False)
    assert np.array_equal(lsm["id"], sgm["id"])
    ok = lsm["ok"] & sgm["ok"]
    grid, i, j = evaluation_grid(truth)
    _, nearest = cKDTree(np.column_stack([truth.x, truth.y])).query(np.column_stack([lsm["x"], lsm["y"]]))
    point_class = truth.cls[nearest]

    def row(label, semi_global):
        v = {k: np.where(semi_global, sgm[k], lsm[k])[ok] for k in ("x", "y", "z", "tier")}
        cells = cells_on_grid(
            v["x"], v["y"], v["z"], None, grid, CellSettings(k=3.0, fallback=False, radius=1), tier=v["tier"]
        )
        dh = cells.heights[i, j] - truth.h
        source = cells.ring[i, j][~truth.water]
        zones = {name: truth.cls == c for c, name in CLASSES.items()}
        zones.update({"bldg edge": truth.edge, "near": truth.near})
        share = " ".join(f"{name} {semi_global[point_class == c].mean():.2f}" for c, name in CLASSES.items())
        print(f"{label}: semi-global share of the points {share}; own cells {np.mean(source == 0):.1%}")
        print("    10 m DSM - true DSM, RMS: " + ", ".join(f"{z} {rms(dh[m]):.2f}" for z, m in zones.items()))

    row("LSM where it accepts (the product)", np.zeros(ok.size, bool))
    row("semi-global everywhere", np.ones(ok.size, bool))
    row("semi-global on forest and city (true class)", np.isin(point_class, (FOREST, CITY)))
    image = gdal.Open(str(paths["images"]["HRG"]["imagery"])).ReadAsArray().astype(float)
    sigma_n = noise_sigma(image)
    q = residual_q(image, lsm["col"], lsm["row"], lsm["rho"], sigma_n)
    print(
        f"HRG noise sigma_n {sigma_n:.2f} DN; q of the refined points by class, median (10th / 90th percentile): "
        + ", ".join(
            f"{name} {np.nanmedian(q[point_class == k]):.2f} ({np.nanpercentile(q[point_class == k], 10):.2f}"
            f" / {np.nanpercentile(q[point_class == k], 90):.2f})"
            for k, name in CLASSES.items()
            if np.isfinite(q[point_class == k]).any()
        )
    )
    for threshold in THRESHOLDS:
        row(f"semi-global where q > {threshold}", np.isfinite(q) & (q > threshold))


if __name__ == "__main__":
    main()
