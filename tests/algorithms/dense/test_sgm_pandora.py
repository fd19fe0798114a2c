"""The dense disparity against CNES pandora's (census 5 x 5, libsgm with the same penalties, winner-takes-all,
V fit, accurate cross-checking) on one epipolar pair of the real Pleiades triplet: the same disparities
where both keep a pixel, and nearly the same pixels kept (the left-right checks differ: pandora matches
image 2 against image 1 again, we read image 2's disparity off the same aggregated volume)."""

import json
import pathlib
import sys

import numpy as np
import pytest
from osgeo import gdal

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dense.epipolar import disparity_range, epipolar_grid
from pushbroom.algorithms.dense.resample import epipolar_image
from pushbroom.algorithms.dense.sgm import SgmParams, disparity

#: where `make setup` installs pandora, out of the venv (Makefile, PANDORA_DIR)
PANDORA_DIR = pathlib.Path(__file__).resolve().parents[3] / "build" / "pandora"
if PANDORA_DIR.is_dir() and str(PANDORA_DIR) not in sys.path:
    sys.path.append(str(PANDORA_DIR))  # after ours: its wheels bring a `tests` package of their own
pandora = pytest.importorskip("pandora", reason=f"pandora is installed into {PANDORA_DIR} by `make setup`")
NODATA = -9999


def write(path, array):
    ds = gdal.GetDriverByName("GTiff").Create(str(path), array.shape[1], array.shape[0], 1, gdal.GDT_Float32)
    ds.GetRasterBand(1).WriteArray(np.where(np.isfinite(array), array, NODATA))
    ds = None


def test_disparities_agree_with_pandora(pleiades_triplet, tmp_path, figures):
    from pandora.constants import Criteria

    m1, m2 = sensors.load(pleiades_triplet[1]), sensors.load(pleiades_triplet[0])
    hr = (0.0, 800.0)
    grid = epipolar_grid(m1, m2, (300, 20, 700, 400), hr)
    epi1 = epipolar_image(pleiades_triplet[1], grid.p, grid.step)
    epi2 = epipolar_image(pleiades_triplet[0], grid.q, grid.step)
    lo, hi = disparity_range(m1, m2, grid, hr)
    d_range = [int(np.floor(lo)), int(np.ceil(hi))]
    params = SgmParams()
    ours = disparity(epi1, epi2, d_range, params)
    write(tmp_path / "left.tif", epi1)
    write(tmp_path / "right.tif", epi2)
    config = {
        "input": {
            "left": {"img": str(tmp_path / "left.tif"), "disp": d_range, "nodata": NODATA},
            "right": {"img": str(tmp_path / "right.tif"), "nodata": NODATA},
        },
        "pipeline": {
            "matching_cost": {
                "matching_cost_method": "census",
                "window_size": 2 * params.census_radius + 1,
                "subpix": 1,
            },
            "optimization": {
                "optimization_method": "sgm",
                "penalty": {"penalty_method": "sgm_penalty", "P1": params.p1, "P2": params.p2},
            },
            "disparity": {"disparity_method": "wta", "invalid_disparity": "NaN"},
            "refinement": {"refinement_method": "vfit"},
            "validation": {
                "validation_method": "cross_checking_accurate",
                "cross_checking_threshold": params.lr_tolerance,
            },
        },
    }
    (tmp_path / "config.json").write_text(json.dumps(config))
    pandora.main(str(tmp_path / "config.json"), str(tmp_path / "out"), False)
    theirs = gdal.Open(str(tmp_path / "out" / "left_disparity.tif")).ReadAsArray()
    mask = gdal.Open(str(tmp_path / "out" / "left_validity_mask.tif")).ReadAsArray()
    kept = np.isfinite(theirs) & ((mask & int(Criteria.PANDORA_MSK_PIXEL_INVALID)) == 0)
    both = kept & np.isfinite(ours)
    diff = np.abs(ours - theirs)[both]
    one = (kept ^ np.isfinite(ours)).mean()
    figures.report(
        "dense disparity vs pandora, pixels kept by both",
        both.mean() * 100,
        "%",
        f"ours {np.isfinite(ours).mean() * 100:.1f} %, pandora {kept.mean() * 100:.1f} %, by one only "
        f"{one * 100:.1f} %; |d - d_pandora| 99.9th percentile {np.percentile(diff, 99.9):.4f} px",
    )
    assert both.mean() > 0.7
    assert np.percentile(diff, 99.9) < 0.01
    assert one < 0.05
