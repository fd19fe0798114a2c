#!/usr/bin/env bash
# make demo: the main job on the built-in sample, through qgis_process as a user's script would run it.
# 1. simulate the default SPOT-5 HRS/HRG triplet over the Jacksboro DEM; 2. create the block with
# footprints on the true DSM; 3. match mass points in the three combinations (region growing);
# 4. select tie points; 5. print what was made. $QGIS_PROCESS is set by the Makefile.
set -euo pipefail
out=$(realpath -m "${1:-demo-output}")
mkdir -p "$out"
qp() { $QGIS_PROCESS run "$@" 2>&1 | grep -v -e XDG_RUNTIME_DIR -e 'setapi() is deprecated' -e '^proj_create'; }

echo "== 1/4 pushbroom:simulatescene (SPOT-5 triplet, 20 x 20 km) -> $out/scene"
qp pushbroom:simulatescene -- CONFIGURATION=0 SIZE_KM=20 SEED=1 POINTS=30 OUTPUT="$out/scene" | tail -n 4
images=()
for f in "$out"/scene/*/IMAGERY.TIF; do images+=("IMAGES=$f"); done

echo "== 2/4 pushbroom:createblock -> $out/block.gpkg"
qp pushbroom:createblock -- "${images[@]}" DEM="$out/scene/dsm.tif" OVERWRITE=true OUTPUT="$out/block.gpkg" | tail -n 3

echo "== 3/4 pushbroom:matchpoints (HRG, HRS1, HRS2; automatic seeds)"
qp pushbroom:matchpoints -- BLOCK="$out/block.gpkg" WORKERS=2 SUMMARY="$out/point_groups.csv" | tail -n 3

echo "== 4/4 pushbroom:selecttiepoints (one per 100 x 100 px cell)"
qp pushbroom:selecttiepoints -- BLOCK="$out/block.gpkg" | tail -n 2

.venv/bin/python scripts/describe_demo.py "$out"
