"""The "Measure control points..." action (toolbar "Pushbroom" and menu "Pushbroom"): opens the measurement
window (ui/measurement_window.py) for the block of the active layer, or for a block GeoPackage the user picks
(the last one is remembered), one window per block, and shows the block's control points on the map. The engine
and the window are imported when the action runs, so that loading the plugin stays fast."""

import os

from qgis.core import Qgis, QgsProviderRegistry, QgsSettings
from qgis.PyQt import sip
from qgis.PyQt.QtGui import QIcon
from qgis.PyQt.QtWidgets import QAction, QFileDialog, QMenu

from ..resource_files import resource_path

ACTION_NAME = "pushbroom_measure"
TOOLBAR_NAME = "PushbroomToolbar"
MENU_NAME = "PushbroomMenu"
LAST_BLOCK = "pushbroom/last_block"


def layer_block(layer):
    """Path of the block GeoPackage `layer` is read from, or None (no layer, not a GeoPackage, not a block)."""
    from ..algorithms.block import Block
    from ..algorithms.errors import InputError

    if layer is None or layer.providerType() != "ogr":
        return None
    path = QgsProviderRegistry.instance().decodeUri("ogr", layer.source()).get("path", "")
    if not path.lower().endswith(".gpkg"):
        return None
    try:
        Block(path).info()
    except InputError:
        return None
    return path


class MeasureAction:
    """The action, its toolbar and menu in the QGIS main window, and the open measurement windows
    ({block file: window}, so that a block has one window and Python keeps it alive)."""

    def __init__(self, iface):
        self.iface = iface
        self.windows = {}
        main = iface.mainWindow()
        self.action = QAction(QIcon(resource_path("icons", "measure.svg")), "Measure control points...", main)
        self.action.setObjectName(ACTION_NAME)
        self.action.setToolTip(
            "Measure control and check points in the images of a Pushbroom block (the block "
            "of the selected layer, or one you pick)"
        )
        self.action.triggered.connect(self.run)
        self.toolbar = iface.addToolBar("Pushbroom")
        self.toolbar.setObjectName(TOOLBAR_NAME)
        self.toolbar.addAction(self.action)
        self.menu = QMenu("&Pushbroom", main)
        self.menu.setObjectName(MENU_NAME)
        self.menu.addAction(self.action)
        bar = main.menuBar()
        help_menu = [a for a in bar.actions() if a.menu() is not None and a.menu().objectName() == "mHelpMenu"]
        bar.insertMenu(help_menu[0] if help_menu else None, self.menu)

    def run(self):
        """Open the window for the active layer's block, else for a block the user picks."""
        path = layer_block(self.iface.activeLayer()) or self.ask_block()
        if path:
            self.open(path)

    def ask_block(self):
        """A block GeoPackage from a file dialog that starts at the last one, or None."""
        path, _ = QFileDialog.getOpenFileName(
            self.iface.mainWindow(),
            "Measure control points: open a block",
            QgsSettings().value(LAST_BLOCK, ""),
            "Pushbroom blocks (*.gpkg)",
        )
        return path or None

    def open(self, block_path):
        """Show (and create if needed) the block's measurement window and its control points layer; returns the
        window, or None after an error shown in the message bar."""
        from ..algorithms.errors import PushbroomError
        from ..ui.measurement_window import MeasurementWindow
        from .control_layer import show_control_points

        key = os.path.normcase(os.path.realpath(block_path))
        window = self.windows.get(key)
        try:
            if window is None or sip.isdeleted(window):
                window = MeasurementWindow(block_path, iface=self.iface, parent=self.iface.mainWindow())
                self.windows[key] = window
                # the map layer follows every edit (undo/redo included) and the residuals of an adjustment
                window.undo_stack.indexChanged.connect(lambda _index, path=block_path: show_control_points(path))
                window.adjusted.connect(lambda _ok, _message, path=block_path: show_control_points(path))
            show_control_points(block_path, create=True)
        except PushbroomError as exc:
            self.iface.messageBar().pushMessage("Pushbroom", str(exc), level=Qgis.Critical, duration=0)
            return None
        QgsSettings().setValue(LAST_BLOCK, block_path)
        window.show()
        window.raise_()
        window.activateWindow()
        return window

    def unload(self):
        """Close the windows and take the action, menu and toolbar out of the main window."""
        for window in self.windows.values():
            if not sip.isdeleted(window):
                window.close()
                window.deleteLater()
        self.windows.clear()
        self.iface.mainWindow().menuBar().removeAction(self.menu.menuAction())
        self.iface.mainWindow().removeToolBar(self.toolbar)
        for widget in (self.menu, self.toolbar, self.action):
            widget.deleteLater()
