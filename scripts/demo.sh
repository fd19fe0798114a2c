#!/usr/bin/env bash
# make demo: the main job on the built-in sample, through qgis_process as a user's script would run it.
# 1. simulate the default SPOT-5 HRS/HRG triplet (20 x 20 km) over the Jacksboro DEM; 2. ONE run of the
# graphical-modeler model resources/models/pushbroom_pipeline.model3 (scripts/build_pipeline_model.py):
# block (footprints on the true DSM), the simulated control/check points (the first 19 control, the rest check),
# a coarse orthoimage that checks IMAGE_NAME, region-growing matching, tie points, bundle adjustment (automatic parameter selection), intersection of
# the mass points (point cloud), 10 m DEM, orthoimage of HRG on the adjusted model and the DEM, accuracy of
# the points and the DEM against the true DSM per land-cover class (report.html, dh raster);
# 3. a QGIS project with every layer styled; 4. print what was made and the tables.
# $QGIS_PROCESS and XDG_RUNTIME_DIR are set by the Makefile.
set -euo pipefail
out=$(realpath -m "${1:-demo-output}")
repo=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
qp() { $QGIS_PROCESS run "$@" 2>&1 | grep -v -e '^proj_create'; }
start=$SECONDS

echo "== 1/3 pushbroom:simulatescene (SPOT-5 triplet, 20 x 20 km) -> $out/scene"
qp pushbroom:simulatescene -- CONFIGURATION=0 SIZE_KM=20 SEED=1 POINTS=30 OUTPUT="$out/scene" | tail -n 4
images=()
for f in "$out"/scene/*/IMAGERY.TIF; do images+=("IMAGES=$f"); done
check=$(tail -n +21 "$out/scene/points.csv" | cut -d, -f1 | paste -sd, -)

echo "== 2/3 model Pushbroom pipeline ($repo/resources/models/pushbroom_pipeline.model3) -> $out (log: pipeline.log)"
qp "$repo/resources/models/pushbroom_pipeline.model3" -- "${images[@]}" APPROX_DEM="$out/scene/dsm.tif" \
  OVERWRITE=true POINTS="$out/scene/points.csv" CHECK_IDS="$check" MEAS_SUFFIX=_meas \
  REFERENCE="$out/scene/dsm.tif" CLASS_RASTER="$out/scene/classes.tif" STEP=5 CELL=10 \
  IMAGE_NAME=HRG THREADS=2 \
  createblock:block="$out/block.gpkg" matchpoints:groups="$out/point_groups.csv" \
  bundleadjust:report="$out/adjustment.html" bundleadjust:residuals="$out/residuals.gpkg" \
  intersectpoints:pointcloud="$out/points.las" interpolatedem:dem="$out/dem.tif" \
  orthorectify:orthoimage="$out/orthoimage_HRG.tif" assessaccuracy:report="$out/report.html" \
  assessaccuracy:table="$out/accuracy.csv" assessaccuracy:dh="$out/dh.tif" > "$out/pipeline.log" \
  || { tail -n 60 "$out/pipeline.log"; exit 1; }
grep -e '^Model processed' "$out/pipeline.log"

echo "== 3/3 QGIS project -> $out/pushbroom_demo.qgz"
.venv/bin/python scripts/make_demo_project.py "$out"

.venv/bin/python scripts/describe_demo.py "$out"
echo -e "\nmake demo: $((SECONDS - start)) s"
