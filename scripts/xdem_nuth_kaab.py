"""Run xdem's Nuth and Kääb (2011) co-registration on one pair of DEMs on the same grid, in xdem's own venv
(build/peers/xdem: xdem needs pyogrio and rasterio wheels, each with its own GDAL, which must never load into
QGIS's process). Used by scripts/coregistration_peers.py only.

    build/peers/xdem/bin/python scripts/xdem_nuth_kaab.py REFERENCE DEM [STABLE_MASK]

REFERENCE and DEM are GeoTIFFs on one grid; STABLE_MASK, a raster on that grid whose non-zero cells are stable.
Prints one JSON object: xdem's version and the translation it applies to DEM (shift_x east, shift_y north, shift_z,
in the CRS's units and metres)."""

import json
import sys

import numpy as np
import xdem


def main(reference: str, dem: str, mask: str | None = None) -> None:
    ref, tba = xdem.DEM(reference), xdem.DEM(dem)
    inlier = None
    if mask:
        import rasterio

        with rasterio.open(mask) as src:
            inlier = src.read(1) != 0
    coreg = xdem.coreg.NuthKaab(max_iterations=30, offset_threshold=0.005, subsample=1.0)
    coreg.fit(ref, tba, inlier_mask=inlier)
    affine = coreg.meta["outputs"]["affine"]
    out = {k: float(affine[k]) for k in ("shift_x", "shift_y", "shift_z")}
    out["xdem"] = xdem.__version__
    out["numpy"] = np.__version__
    print(json.dumps(out))


if __name__ == "__main__":
    main(*sys.argv[1:])
