"""Issue 5 acceptance "Real data": DSMs from real Pleiades pixels, matched (match_block), intersected
(surface.intersection) and gridded (surface.tin_dem) by the engine.

Ventoux pair (../shared/data/pleiades_pair_ventoux, RPC from the .geom with the crops' offsets
(5000, 5000) and (4915, 5162)): the crops (500 x 500 px of 0.5 m) overlap by only ~170 rows (at
540 m, left rows 327..500 fall inside the right crop), so the DSM covers ~200 m x 85 m of forested
slope, about 3 x 1 postings of the SRTM tile (3": 66 m E-W, 93 m N-S). Matching STEP 2 px (1 m
nodes); DSM cell 2 m: twice the node spacing, so every cell is interpolated from its own points,
while a cell near the SRTM's 90 m would leave one or two cells on this overlap. dh = DSM - SRTM
with SRTM's EGM96 heights made ellipsoidal (h = H + N, N ~ 50 m here; quality.height_differences,
reference bilinear onto the 2 m grid). The two RPCs have a constant relative bias (mean
intersection residuals -2.3 / +2.3 px in columns, -0.6 / +0.6 px in rows, 0.07 px spread), across
the epipolar direction, so it does not move the heights, and is left. What remains of dh is
mostly a west-east ramp of ~0.13 m/m (26 m over the 200 m): it would take ~17 px of parallax error
across 400 px to come from the images, far beyond an RPC's bias, so it is the SRTM's 66-93 m
postings on ravine relief (or their registration); removed as a plane, dh has an NMAD of ~3.5 m.
The median (+4.8 m) is of the order of the canopy over the C-band SRTM surface. The 1 m and 5 m
DSMs are made beside the asserted 2 m one: the NMAD moves with the cell (9.2 .. 11.1 m), since
each cell size leaves other gaps on the same ramp; the 2 m result (9.9 m) is held to 12 m, above
that spread, as the coarse-to-fine matcher's in test_hierarchical_real.

Region growing's matching of both (conftest.py) is shared with test_hierarchical_real and
test_matching_pleiades. Pleiades triplet (pleiades_scene: img_02 reference, img_01 forward, img_03
backward; STEP 3 px, 1.5 m nodes): the 0.5 m DSM from the three-ray points (groups 2 and 3); gaps
where a triangle is longer than 3 m (two node spacings: one missing node is bridged, larger holes
are not). Coverage = share of defined cells among those whose centre, at the points' median height,
lies in all three images. Internal consistency: each pair (img_02-img_01, img_02-img_03,
img_01-img_03) matched on its own (match_block of 2 images), intersected and gridded on the same
0.5 m lattice (Grid.covering aligns on multiples of the cell); median and NMAD of the pairwise
differences over the common footprint, with the supplied RPCs and after the RPC bias adjustment of
test_adjust_pleiades (shifts of img_01 and img_03, img_02 fixed, 10 px priors) on tie points of the
triplet's matching. Before it, the pairs' DSMs are offset by ~2.4 m (an along-track bias of 0.5 px
is 2.3 m of height at B/H 0.11); after it, the medians are ~0.1 m. The NMAD bound 0.6 m is the
height precision of a difference of two B/H 0.11 pair DSMs at 0.1 px matching precision (sqrt(2) x
0.1 x 0.5 m / 0.11 = 0.64 m)."""
import numpy as np
import pytest
from osgeo import gdal

from tests.helpers.real_dsm import CELL, VENTOUX_CELL, check_pair_consistency, footprint_mask, report_srtm_comparison

pytestmark = [pytest.mark.slow, pytest.mark.real, pytest.mark.ratchet]

#: m, against SRTM: issue 5's acceptance on the 2 m DSM. The NMAD is mostly the ramp's and moves with the cell
#: (9.2-11.1 m, docstring), not with the machine; the matcher's own error is held by the NMAD without the ramp (< 5 m)
MAX_MEDIAN, MAX_NMAD = 5.0, 10.0
MIN_COVERAGE = 0.6
MAX_PAIR_MEDIAN, MAX_PAIR_NMAD = 0.25, 0.6          # m, after the bias adjustment


def test_ventoux_dsm_against_srtm(ventoux_region_growing, figures):
    points, result, srtm_dh = ventoux_region_growing
    report_srtm_comparison(srtm_dh, figures)
    assert result.ok.all() and len(result) == len(points) > 5000, (len(points), result.status_counts())
    s, detrended = srtm_dh["stats"][VENTOUX_CELL], srtm_dh["detrended"]
    # the geoid: the same DSM against the SRTM taken as ellipsoidal differs by N(EGM96) ~ 50 m near Mont Ventoux
    n = srtm_dh["geoid"]
    assert 48.0 < n.mean() < 52.0 and np.ptp(n) < 0.1, (n.mean(), np.ptp(n))
    assert abs(s.median) < MAX_MEDIAN and s.nmad < MAX_NMAD, s
    # what is left after the median: a ramp over the overlap, at the scale of the SRTM postings (detrended)
    assert s.n > 2000 and detrended.nmad < 5.0, (s.n, detrended)


def test_triplet_dsm_coverage(region_growing_triplet_dsms):
    dsms = region_growing_triplet_dsms
    dem = dsms["triplet"]
    ds = gdal.Open(str(dsms["path"]))
    band = ds.GetRasterBand(1)
    written = band.ReadAsArray().astype(float)
    defined = written != band.GetNoDataValue()
    assert ds.GetGeoTransform()[1] == CELL and np.array_equal(defined, np.isfinite(dem.heights))
    inside = footprint_mask(dem.grid, dsms["srs"], dsms["models"], dsms["height"])
    coverage = defined[inside].mean()
    assert coverage > MIN_COVERAGE and (defined & ~inside).sum() < 0.01 * defined.sum()


def test_pair_dsms_agree_after_bias_adjustment(region_growing_triplet_dsms, figures):
    check_pair_consistency(region_growing_triplet_dsms, "region-growing", MAX_PAIR_MEDIAN, MAX_PAIR_NMAD, figures)
