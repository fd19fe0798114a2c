"""How do the Ventoux pair's DSM - SRTM statistics depend on the coarse-to-fine matcher's grid spacing
(issue 7's Ventoux point)? match_coarse_to_fine on the two Pleiades crops with grid points every 2
(region growing's nodes, as tests/real/test_coarse_to_fine_real.py), 5 and 10 px (or the GRID arguments),
the points intersected with the supplied RPCs and gridded at 1, 2 and 5 m, each DSM against the SRTM
tile (EGM96 -> ellipsoidal) with the real-data tests' code (tests.helpers.real_dsm). Needs the real
data sets of the tests (tests/conftest.py, SHARED_DATA)."""

import pathlib
import sys
import tempfile

from pushbroom.algorithms import sensors
from pushbroom.algorithms.matching.coarse_to_fine import CoarseToFineParams, match_coarse_to_fine
from pushbroom.algorithms.matching.imagery import Image
from tests.helpers.real_dsm import cut, srtm_comparison

ROOT = pathlib.Path(__file__).resolve().parents[1]

DATA = ROOT.parent / "shared" / "data" / "pleiades_pair_ventoux"
CELLS = (1.0, 2.0, 5.0)


def main(grids):
    paths = [DATA / "left_image.tif", DATA / "right_image.tif"]
    models = [sensors.load(p) for p in paths]
    for grid in grids:
        points = match_coarse_to_fine(
            [Image(p) for p in paths], models, names=[p.stem for p in paths], params=CoarseToFineParams(grid=grid)
        )
        result = cut({1: models[0], 2: models[1]}, points.observations)
        with tempfile.TemporaryDirectory() as tmp:
            c = srtm_comparison(result, str(DATA / "N44E005.hgt"), CELLS, 2.0, pathlib.Path(tmp))
        print(f"grid {grid} px: {len(points)} points; without the 2 m DSM's plane NMAD {c['detrended'].nmad:.2f} m")
        for cell, s in c["stats"].items():
            print(f"  {cell:g} m DSM - SRTM: N {s.n:6d}, median {s.median:+6.2f} m, NMAD {s.nmad:5.2f} m")


if __name__ == "__main__":
    if not DATA.is_dir():
        sys.exit(f"{DATA} is missing (the shared data sets)")
    main([int(g) for g in sys.argv[1:]] or [2, 5, 10])
