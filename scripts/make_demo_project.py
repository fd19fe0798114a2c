"""Write OUT/pushbroom_demo.qgz, a QGIS project of what `make demo` made, every layer styled with the
plugin's QML files (resources/styles): the orthoimage, the DEM, the dh raster, the true orthoimage,
the block's footprints, mass and tie points (by point group), control/check points and their residual
vectors. The LAS point cloud is added where this QGIS reads point clouds (PDAL provider).

    QT_QPA_PLATFORM=offscreen .venv/bin/python scripts/make_demo_project.py demo-output
"""

import os
import sys

from qgis.core import (
    QgsApplication,
    QgsPointCloudLayer,
    QgsProject,
    QgsProviderRegistry,
    QgsRasterLayer,
    QgsVectorLayer,
)

from pushbroom.algorithms.atomic import atomic_path
from pushbroom.plugin.styles import resolve_application_font
from pushbroom.resource_files import resource_path

#: (file in OUT, layer name in a GeoPackage or None, layer name, QML in resources/styles or None, kind);
#: top of the layer list first
LAYERS = [
    ("residuals.gpkg", None, "Residual vectors (control/check points)", "residual_vectors.qml", "vector"),
    ("block.gpkg", "control_points", "Control and check points", "control_points.qml", "vector"),
    ("block.gpkg", "tie_points", "Tie points", "points_by_group.qml", "vector"),
    ("block.gpkg", "mass_points", "Mass points (on HRG, by group)", "points_by_group.qml", "vector"),
    ("block.gpkg", "footprints", "Footprints", "footprints.qml", "vector"),
    ("points.las", None, "Point cloud", None, "pointcloud"),
    ("dh.tif", None, "dh of the DEM against the true DSM", "dh.qml", "raster"),
    ("dem.tif", None, "DEM (10 m)", "dem.qml", "raster"),
    ("orthoimage_HRG.tif", None, "Orthoimage HRG (adjusted model, produced DEM)", None, "raster"),
    ("scene/orthoimage.tif", None, "True orthoimage (simulator)", None, "raster"),
]


def layer(out, file_name, sublayer, name, kind):
    """The QGIS layer, or None where its file is missing or QGIS cannot read it."""
    path = os.path.join(out, file_name)
    if not os.path.exists(path):
        return None
    if kind == "raster":
        result = QgsRasterLayer(path, name, "gdal")
    elif kind == "pointcloud":
        if "pdal" not in QgsProviderRegistry.instance().providerList():
            return None
        result = QgsPointCloudLayer(path, name, "pdal")
    else:
        result = QgsVectorLayer(f"{path}|layername={sublayer}" if sublayer else path, name, "ogr")
    return result if result.isValid() else None


def main(out):
    out = os.path.abspath(out)
    app = QgsApplication([], False)
    app.initQgis()
    resolve_application_font(app)
    project = QgsProject.instance()
    added, skipped = [], []
    for file_name, sublayer, name, qml, kind in LAYERS:
        lyr = layer(out, file_name, sublayer, name, kind)
        if lyr is None:
            skipped.append(file_name if sublayer is None else f"{file_name}|{sublayer}")
            continue
        if qml:
            message, ok = lyr.loadNamedStyle(resource_path("styles", qml))
            if not ok:
                sys.exit(f"cannot apply {qml} to {name}: {message}")
        project.addMapLayer(lyr, False)
        project.layerTreeRoot().addLayer(lyr)
        added.append(name)
    dem = project.mapLayersByName("DEM (10 m)")
    if dem:
        project.setCrs(dem[0].crs())
    target = os.path.join(out, "pushbroom_demo.qgz")
    # beside the target, so that layer paths stay relative; not hidden: QGIS names the .qgs inside the
    # archive after the file's base name
    with atomic_path(target, "the demo project", hidden=False) as tmp:
        if not project.write(tmp):
            sys.exit(f"cannot write {target}: {project.error()}")
    print(
        f"{target}: {len(added)} layers ({', '.join(added)})"
        + (f"; not added (missing or unreadable here): {', '.join(skipped)}" if skipped else "")
    )
    app.exitQgis()


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "demo-output")
