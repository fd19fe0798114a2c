#!/usr/bin/env bash
# make demo: the main job on the built-in sample, through qgis_process as a user's script would run it.
# 1. simulate the default SPOT-5 HRS/HRG triplet over the Jacksboro DEM; 2. create the block with
# footprints on the true DSM; 3. match mass points in the three combinations (region growing);
# 4. select tie points; 5. import the simulated control/check points (the first 19 control, the rest
# check); 6. bundle adjustment (report, residual vectors, tie point heights against the true DTM as in
# K Table 4); 7. intersect the mass points with the adjusted models (point cloud); 8. print what was made
# and the adjustment's tables. $QGIS_PROCESS is set by the Makefile.
set -euo pipefail
out=$(realpath -m "${1:-demo-output}")
mkdir -p "$out"
qp() { $QGIS_PROCESS run "$@" 2>&1 | grep -v -e XDG_RUNTIME_DIR -e 'setapi() is deprecated' -e '^proj_create'; }

echo "== 1/7 pushbroom:simulatescene (SPOT-5 triplet, 20 x 20 km) -> $out/scene"
qp pushbroom:simulatescene -- CONFIGURATION=0 SIZE_KM=20 SEED=1 POINTS=30 OUTPUT="$out/scene" | tail -n 4
images=()
for f in "$out"/scene/*/IMAGERY.TIF; do images+=("IMAGES=$f"); done

echo "== 2/7 pushbroom:createblock -> $out/block.gpkg"
qp pushbroom:createblock -- "${images[@]}" DEM="$out/scene/dsm.tif" OVERWRITE=true OUTPUT="$out/block.gpkg" | tail -n 3

echo "== 3/7 pushbroom:matchpoints (HRG, HRS1, HRS2; automatic seeds)"
qp pushbroom:matchpoints -- BLOCK="$out/block.gpkg" WORKERS=2 SUMMARY="$out/point_groups.csv" | tail -n 3

echo "== 4/7 pushbroom:selecttiepoints (one per 100 x 100 px cell)"
qp pushbroom:selecttiepoints -- BLOCK="$out/block.gpkg" | tail -n 2

echo "== 5/7 pushbroom:importpoints (simulated points.csv: 19 control, the rest check)"
check=$(tail -n +21 "$out/scene/points.csv" | cut -d, -f1 | paste -sd, -)
qp pushbroom:importpoints -- BLOCK="$out/block.gpkg" INPUT="$out/scene/points.csv" MEAS_SUFFIX=_meas \
  CHECK_IDS="$check" | grep -e '^points in the block'

echo "== 6/7 pushbroom:bundleadjust (automatic parameter selection; reference: the true DTM) -> $out/adjustment.html"
qp pushbroom:bundleadjust -- BLOCK="$out/block.gpkg" FREE=auto REFERENCE_DEM="$out/scene/dtm.tif" \
  REPORT="$out/adjustment.html" RESIDUALS="$out/residuals.gpkg" > "$out/bundleadjust.log" \
  || { cat "$out/bundleadjust.log"; exit 1; }
grep -e '^selected' -e '^ *sigma_0 = ' "$out/bundleadjust.log" | tail -n 2

echo "== 7/7 pushbroom:intersectpoints (mass points, adjusted models) -> $out/points.las"
qp pushbroom:intersectpoints -- BLOCK="$out/block.gpkg" POINTS=0 OUTPUT="$out/points.las" | grep -e 'written to'

.venv/bin/python scripts/describe_demo.py "$out"
