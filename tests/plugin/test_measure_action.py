"""The "Measure control points..." action (plugin/measure_action.py) in the pytest-qgis main window and the
control points layer on the map (plugin/control_layer.py, resources/styles/control_points.qml)."""

import sys
import types

import numpy as np
import pytest
from osgeo import ogr
from qgis.core import (
    NULL,
    Qgis,
    QgsCategorizedSymbolRenderer,
    QgsExpressionContext,
    QgsExpressionContextUtils,
    QgsProject,
    QgsSettings,
    QgsSymbolLayer,
    QgsVectorLayer,
)
from qgis.PyQt import sip
from qgis.PyQt.QtCore import QCoreApplication, QEvent, pyqtSignal
from qgis.PyQt.QtWidgets import QAction, QMainWindow, QToolBar, QUndoCommand, QUndoStack

import pushbroom
from pushbroom.algorithms.adjustment.observations import POINT_DTYPE, Observations
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.block.schema import create_schema
from pushbroom.algorithms.errors import InputError
from pushbroom.plugin.control_layer import find_control_layer, show_control_points
from pushbroom.plugin.measure_action import ACTION_NAME, LAST_BLOCK, layer_block


def flush_deletes():
    QCoreApplication.sendPostedEvents(None, QEvent.DeferredDelete)


@pytest.fixture
def points_block(tmp_path):
    """An image-less block with one control and one check point."""
    path = tmp_path / "block.gpkg"
    create_schema(path)
    points = np.array(
        [
            ("C1", "control", 7.0, 45.0, 100.0, 2.5, 2.5, 2.2),
            ("K1", "check", 7.01, 45.01, 120.0, np.nan, np.nan, np.nan),
        ],
        POINT_DTYPE,
    )
    Block(path).save_control_points(Observations(points), names={})
    return path


@pytest.fixture
def project(qgis_new_project):
    yield QgsProject.instance()
    QgsProject.instance().removeAllMapLayers()


def test_init_gui_adds_the_action_and_unload_removes_it(qgis_iface):
    main = qgis_iface.mainWindow()
    plugin = pushbroom.classFactory(qgis_iface)
    plugin.initGui()
    try:
        action = main.findChild(QAction, ACTION_NAME)
        assert action is not None and not action.icon().isNull()
        assert action.text() == "Measure control points..."
        toolbars = [t for t in main.findChildren(QToolBar) if action in t.actions()]
        assert [t.windowTitle() for t in toolbars] == ["Pushbroom"]
        menus = [a.menu() for a in main.menuBar().actions() if a.menu() and action in a.menu().actions()]
        assert [m.title() for m in menus] == ["&Pushbroom"]
    finally:
        plugin.unload()
    flush_deletes()
    assert main.findChild(QAction, ACTION_NAME) is None
    assert not [a for a in main.menuBar().actions() if a.text() == "&Pushbroom"]
    assert not [t for t in main.findChildren(QToolBar) if t.windowTitle() == "Pushbroom"]


def test_layer_block_is_the_geopackage_of_a_block_layer(points_block, tmp_path):
    footprints = QgsVectorLayer(f"{points_block}|layername=footprints", "footprints", "ogr")
    assert layer_block(footprints) == str(points_block)
    other = tmp_path / "other.gpkg"
    ds = ogr.GetDriverByName("GPKG").CreateDataSource(str(other))
    ds.CreateLayer("things", geom_type=ogr.wkbPoint)
    ds = None
    assert layer_block(QgsVectorLayer(f"{other}|layername=things", "things", "ogr")) is None
    assert layer_block(QgsVectorLayer("Point?crs=EPSG:4326", "memory", "memory")) is None
    assert layer_block(None) is None


def ring_size(layer, role, residual):
    """Evaluated (enabled, diameter mm) of the residual ring of a point with `role` and `residual_px`."""
    categories = layer.renderer().categories()
    ring = categories[layer.renderer().categoryIndexForValue(role)].symbol().symbolLayer(0)
    feature = next(layer.getFeatures())
    feature["residual_px"] = residual
    context = QgsExpressionContext(QgsExpressionContextUtils.globalProjectLayerScopes(layer))
    context.setFeature(feature)
    props = ring.dataDefinedProperties()
    enabled, _ = props.valueAsBool(QgsSymbolLayer.PropertyLayerEnabled, context, True)
    size, _ = props.valueAsDouble(QgsSymbolLayer.PropertySize, context, ring.size())
    return enabled, size


def test_control_points_layer_is_added_once_styled_and_reloaded(points_block, project):
    layer = show_control_points(points_block, project)
    assert layer is not None and layer.isValid() and layer.featureCount() == 2
    assert show_control_points(points_block, project) is layer
    assert len(project.mapLayers()) == 1 and find_control_layer(points_block, project) is layer
    renderer = layer.renderer()
    assert isinstance(renderer, QgsCategorizedSymbolRenderer) and renderer.classAttribute() == "role"
    assert {c.value() for c in renderer.categories()} == {"control", "check"}
    assert layer.labelsEnabled()

    # the bundle adjustment adds `residual_px` through its own connection; a refresh shows the field
    ds = ogr.Open(str(points_block), 1)
    table = ds.GetLayerByName("control_points")
    table.CreateField(ogr.FieldDefn("residual_px", ogr.OFTReal))
    for feat in table:
        if feat["name"] == "C1":
            feat["residual_px"] = 2.0
            table.SetFeature(feat)
    ds = None
    assert show_control_points(points_block, project) is layer
    assert layer.fields().indexOf("residual_px") >= 0
    values = {f["name"]: f["residual_px"] for f in layer.getFeatures()}
    assert values["C1"] == 2.0 and values["K1"] == NULL
    for role in ("control", "check"):
        assert ring_size(layer, role, None)[0] is False
        (on_small, small), (on_big, big) = ring_size(layer, role, 0.5), ring_size(layer, role, 2.0)
        assert on_small and on_big and small == pytest.approx(5.5) and big == pytest.approx(10.0)


def test_a_block_without_points_gets_an_empty_layer_on_request(tmp_path, project):
    path = tmp_path / "empty.gpkg"
    create_schema(path)
    assert show_control_points(path, project) is None and not project.mapLayers()
    layer = show_control_points(path, project, create=True)
    assert layer.isValid() and layer.featureCount() == 0 and list(project.mapLayers().values()) == [layer]
    Block(path).save_control_points(
        Observations(np.array([("C1", "control", 7.0, 45.0, 100.0, 2.5, 2.5, 2.2)], POINT_DTYPE)), names={}
    )
    assert show_control_points(path, project) is layer and layer.featureCount() == 1


class FakeWindow(QMainWindow):
    """Stands in for ui.measurement_window.MeasurementWindow: records how it was created; its undo stack
    and `adjusted` signal are what the plugin follows."""

    created = []
    adjusted = pyqtSignal(bool, str)

    def __init__(self, block_path, iface=None, parent=None):
        super().__init__(parent)
        self.block_path, self.iface = block_path, iface
        self.undo_stack = QUndoStack(self)
        FakeWindow.created.append(self)


class AddPoint(QUndoCommand):
    """Writes one more control point into the block (as the window's commands do)."""

    def __init__(self, path, name):
        super().__init__(name)
        self.path, self.name = path, name

    def redo(self):
        Block(self.path).measurement_store().put_point(self.name, "control", 7.0, 45.0, 100.0, 2.5, 2.5, 2.2)


class BrokenWindow(QMainWindow):
    def __init__(self, block_path, iface=None, parent=None):
        raise InputError(f"block {block_path} is broken")


@pytest.fixture
def plugin_with(qgis_iface, monkeypatch):
    """plugin_with(window_class): the plugin, its GUI initialised with `window_class` as the measurement
    window; unloaded afterwards."""
    loaded = []

    def load(window_class):
        module = types.ModuleType("pushbroom.ui.measurement_window")
        module.MeasurementWindow = window_class
        monkeypatch.setitem(sys.modules, "pushbroom.ui.measurement_window", module)
        plugin = pushbroom.classFactory(qgis_iface)
        plugin.initGui()
        loaded.append(plugin)
        return plugin

    yield load
    for plugin in loaded:
        plugin.unload()
    flush_deletes()


def test_action_opens_one_window_per_block_for_the_active_layer(qgis_iface, plugin_with, points_block, project):
    FakeWindow.created.clear()
    plugin = plugin_with(FakeWindow)
    footprints = QgsVectorLayer(f"{points_block}|layername=footprints", "footprints", "ogr")
    project.addMapLayer(footprints)
    qgis_iface.setActiveLayer(footprints)
    action = qgis_iface.mainWindow().findChild(QAction, ACTION_NAME)
    action.trigger()
    action.trigger()
    assert len(FakeWindow.created) == 1
    window = FakeWindow.created[0]
    assert window.block_path == str(points_block) and window.iface is qgis_iface and window.isVisible()
    assert window.parent() is qgis_iface.mainWindow()
    assert find_control_layer(points_block, project) is not None and len(project.mapLayers()) == 2
    assert QgsSettings().value(LAST_BLOCK) == str(points_block)
    layer = find_control_layer(points_block, project)
    count = layer.featureCount()
    window.undo_stack.push(AddPoint(str(points_block), "NEW1"))
    assert layer.featureCount() == count + 1  # the map follows an edit at once
    plugin.unload()
    flush_deletes()
    assert sip.isdeleted(window)


def test_a_block_the_window_cannot_open_gives_a_message(qgis_iface, plugin_with, points_block, project):
    plugin = plugin_with(BrokenWindow)
    assert plugin.measure.open(str(points_block)) is None
    assert f"Pushbroom:block {points_block} is broken" in qgis_iface.messageBar().get_messages(Qgis.Critical)
    assert not plugin.measure.windows and not project.mapLayers()
