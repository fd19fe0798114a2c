"""The block's control and check points (GeoPackage layer `control_points`) as a layer of the QGIS project,
styled with resources/styles/control_points.qml: role by colour and shape (control: red triangle, check: blue
circle), the RMS image residual r (px) of the last adjustment (field `residual_px`) by a ring of diameter
min(4 + 3 r, 16) mm and in the label; no ring before an adjustment (NULL or no field)."""

import os

from qgis.core import QgsProject, QgsProviderRegistry, QgsVectorLayer

from ..algorithms.block import Block
from ..resource_files import resource_path

LAYER_NAME = "Control and check points"


def _file_key(path):
    return os.path.normcase(os.path.realpath(path))


def find_control_layer(block_path, project=None):
    """The project's layer of the block's `control_points`, or None."""
    project = project or QgsProject.instance()
    key = _file_key(block_path)
    for layer in project.mapLayers().values():
        if layer.providerType() != "ogr":
            continue
        parts = QgsProviderRegistry.instance().decodeUri("ogr", layer.source())
        if parts.get("layerName") == Block.CONTROL_LAYER and _file_key(parts.get("path", "")) == key:
            return layer
    return None


def create_control_points(block_path):
    """Create the block's (empty) `control_points` layer and `image_measurements` table where missing, in one
    transaction, so that the map shows the points from the first one measured."""
    Block(block_path).create_control_points()


def show_control_points(block_path, project=None, create=False):
    """Add the block's control points to `project` (default: the current project) as a styled layer, or, when
    it is there already, reload it (points written since, the `residual_px` field an adjustment adds) and
    repaint it. Returns the layer; None while the block has no `control_points` layer yet and not `create`."""
    project = project or QgsProject.instance()
    layer = find_control_layer(block_path, project)
    if layer is not None:
        if not layer.isEditable():
            layer.reload()
        layer.triggerRepaint()
        return layer
    if create:
        create_control_points(block_path)
    layer = QgsVectorLayer(Block(block_path).layer_source(Block.CONTROL_LAYER), LAYER_NAME, "ogr")
    if not layer.isValid():
        return None
    layer.loadNamedStyle(resource_path("styles", "control_points.qml"))
    project.addMapLayer(layer)
    return layer
