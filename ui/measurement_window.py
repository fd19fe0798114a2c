"""The measurement window (issue 6): control/check points of a block measured in its images and on a
reference map, written to the block GeoPackage at once.

Layout: one ImageView per block image in raw sensor geometry (HRS shown with its 2:1 aspect
correction: aspect = ground size of a row / ground size of a column at the image centre), the
reference view (QGIS map canvas with a DEM for heights), the point editor and the point table with
the residuals of the last adjustment.

Workflow: pick or create a point; a click on the reference sets its ground position (X, Y from the
map, Z from the DEM), the predictions of the current block models are marked in every image and the
views jump there; a click in an image measures the point there and least-squares matching transfers
it into the images where it is not measured yet, as pending results (with rho) to accept or reject.
A point measured in an image before it has ground coordinates is stored at once at a provisional
ground position.

The state and the edits are the MeasurementSession's (algorithms/measurement/session.py): the window
presents it, turns clicks and keys into its calls and pushes each of its edits onto a QUndoStack
(ui/commands.py). Every edit is written to the block when it is done, so closing, a crash or a killed
QGIS loses nothing. 'Adjust now' runs pushbroom:bundleadjust in a QgsTask and then reloads the models
and the residuals."""

import math
import os
import weakref

from qgis.core import Qgis, QgsProject, QgsRasterLayer
from qgis.gui import QgsMessageBar
from qgis.PyQt.QtCore import Qt, pyqtSignal
from qgis.PyQt.QtGui import QKeySequence
from qgis.PyQt.QtWidgets import (
    QAction,
    QFileDialog,
    QFrame,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QMainWindow,
    QProgressBar,
    QSizePolicy,
    QSplitter,
    QToolButton,
    QUndoStack,
    QVBoxLayout,
    QWidget,
)

from ..algorithms.errors import PushbroomError
from ..algorithms.geodesy import metres_per_degree
from ..algorithms.measurement.session import SIGMA_KEYS, MeasurementSession, residual_magnitudes
from .adjust_task import AdjustRunner
from .commands import EditCommand
from .image_view import ImageView, Marker, Vector
from .point_editor import PointEditor
from .point_table import CRITICAL, PointTable
from .reference_view import ReferenceView

#: screen px per image column of "zoom to prediction"
DETAIL_ZOOM = 4.0
#: residual vectors: screen px per image px
VECTOR_SCALE = 40.0


def display_aspect(model, h):
    """Ground size of a row / ground size of a column at the image centre and height h (HRS 0.5, HRG 1):
    the displayed height of a row for a column width of 1."""
    cols, rows = model.size
    c, r = 0.5 * cols, 0.5 * rows
    lon, lat = model.image_to_ground([c, c + 1.0, c], [r, r, r + 1.0], [h, h, h])
    me, mn = metres_per_degree(lat[0], h)
    column, row = (math.hypot((lon[k] - lon[0]) * me, (lat[k] - lat[0]) * mn) for k in (1, 2))
    return row / column if column > 0 and math.isfinite(row / column) else 1.0


class ImagePane(QFrame):
    """One block image: a header (name, state of the current point there, accept/reject of a pending
    transfer) over its ImageView; a coloured frame marks the current image. Signals carry the image id:
    clicked(image id, col, row), acceptRequested(image id), rejectRequested(image id)."""

    clicked = pyqtSignal(int, float, float)
    acceptRequested = pyqtSignal(int)
    rejectRequested = pyqtSignal(int)

    def __init__(self, image_id, name, parent=None):
        super().__init__(parent)
        self.image_id, self.name = image_id, name
        self.setFrameShape(QFrame.Box)
        self.setLineWidth(2)
        self.view = ImageView(self)
        self.view.title(name)
        self.status = QLabel(name, self)
        self.status.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Preferred)  # long texts never resize the view
        self.accept = QToolButton(self)
        self.accept.setText("\u2713")
        self.accept.setToolTip(f"Accept the LSM transfer into {name} (Return: all images)")
        self.reject = QToolButton(self)
        self.reject.setText("\u2717")
        self.reject.setToolTip(f"Reject the LSM transfer into {name} (Delete: all images)")
        self.view.clicked.connect(self._clicked)
        self.accept.clicked.connect(self._accept)
        self.reject.clicked.connect(self._reject)
        header = QHBoxLayout()
        header.setContentsMargins(4, 0, 4, 0)
        header.addWidget(self.status, 1)
        header.addWidget(self.accept)
        header.addWidget(self.reject)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(1, 1, 1, 1)
        layout.setSpacing(1)
        layout.addLayout(header)
        layout.addWidget(self.view, 1)
        self.set_pending(False)
        self.set_current(False)

    def _clicked(self, col, row):
        self.clicked.emit(self.image_id, col, row)

    def _accept(self):
        self.acceptRequested.emit(self.image_id)

    def _reject(self):
        self.rejectRequested.emit(self.image_id)

    def set_pending(self, pending):
        self.accept.setEnabled(pending)
        self.reject.setEnabled(pending)

    def set_current(self, current):
        self.setStyleSheet("ImagePane { border: 2px solid %s; }" % ("#ff3cff" if current else "#808080"))


class MeasurementWindow(QMainWindow):
    """See the module docstring; `session` holds the state. Scripting methods (the GUI actions call the
    same): new_point, select_point, edit_point, set_ground, click_image, accept_pending, reject_pending,
    delete_point, adjust_now (signal adjusted(ok, message)), import_csv, export_csv, import_points_file,
    export_points_file."""

    adjusted = pyqtSignal(bool, str)

    def __init__(self, block_path, iface=None, parent=None, reference_layers=None, dem_path=None):
        super().__init__(parent)
        self.block_path = os.fspath(block_path)
        self.iface = iface
        self.undo_stack = QUndoStack(self)
        # the session reaches back weakly: no reference cycle keeps the window's widgets (the QGIS
        # canvas) alive until a garbage collection, which may run after QGIS has exited
        push = weakref.WeakMethod(self._push)
        self.session = MeasurementSession(self.block_path, record=lambda edit: push()(edit))
        self.current_image = next(iter(self.session.image_names), None)
        self.runner = AdjustRunner(self.block_path, self)
        self.runner.finished.connect(self._adjust_finished)
        self.setWindowTitle(f"Pushbroom measurement: {os.path.basename(self.block_path)}")
        self._build(reference_layers, dem_path)
        self.undo_stack.indexChanged.connect(self._stack_changed)
        self.refresh()
        self.resize(1280, 800)

    # --- construction ----------------------------------------------------------------------------------
    def _build(self, reference_layers, dem_path):
        session = self.session
        self.panes, self.image_views = {}, {}
        images = QWidget(self)
        grid = QHBoxLayout(images)
        grid.setContentsMargins(0, 0, 0, 0)
        grid.setSpacing(2)
        for image_id, name in session.image_names.items():
            pane = ImagePane(image_id, name, images)
            try:
                pane.view.open(
                    session.image_paths[image_id], display_aspect(session.models[image_id], session.default_height)
                )
            except PushbroomError as exc:  # a moved or deleted raster: the other images stay usable
                pane.view.title(f"{name}: {exc}")
            pane.view.set_vector_scale(VECTOR_SCALE)
            pane.clicked.connect(self._view_clicked)
            pane.acceptRequested.connect(self._accept_clicked)
            pane.rejectRequested.connect(self._reject_clicked)
            pane.view.setToolTip(
                f"{name}: click to measure the point here (the other images get LSM transfers); "
                "wheel zoom, drag pan, +/- zoom"
            )
            grid.addWidget(pane, 1)
            self.panes[image_id], self.image_views[image_id] = pane, pane.view
        layers = reference_layers
        if layers is None:
            layers = self._project_rasters() if self.iface is not None else []
        self.reference = ReferenceView(self.block_path, layers, dem_path, session.default_height, self)
        self.reference.clicked.connect(self._reference_clicked)
        self.reference.message.connect(self.show_message)
        top = QSplitter(Qt.Horizontal, self)
        top.addWidget(images)
        top.addWidget(self.reference)
        top.setStretchFactor(0, len(self.panes))
        top.setStretchFactor(1, 1)
        top.setSizes([300 * len(self.panes), 320])
        self.editor = PointEditor(self.reference.crs().authid() or "canvas CRS", self)
        self.editor.applied.connect(self._editor_applied)
        self.table = PointTable(self)
        self.table.pointSelected.connect(self._table_selected)
        bottom = QSplitter(Qt.Horizontal, self)
        bottom.addWidget(self.editor)
        bottom.addWidget(self.table)
        bottom.setStretchFactor(1, 1)
        bottom.setSizes([330, 950])
        main = QSplitter(Qt.Vertical, self)
        main.addWidget(top)
        main.addWidget(bottom)
        main.setStretchFactor(0, 3)
        main.setStretchFactor(1, 1)
        main.setSizes([520, 230])
        self.message_bar = QgsMessageBar(self)
        central = QWidget(self)
        layout = QVBoxLayout(central)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.setSpacing(2)
        layout.addWidget(self.message_bar)
        layout.addWidget(main, 1)
        self.setCentralWidget(central)
        self.work_area = [images, self.reference, self.table]
        self._build_actions()
        self.point_label = QLabel(self)
        self.progress = QProgressBar(self)
        self.progress.setMaximumWidth(160)
        self.progress.hide()
        self.runner.progressChanged.connect(self._progress)
        self.statusBar().addPermanentWidget(self.point_label)
        self.statusBar().addPermanentWidget(self.progress)
        self._highlight_image()

    @staticmethod
    def _project_rasters():
        return [
            layer for layer in QgsProject.instance().layerTreeRoot().layerOrder() if isinstance(layer, QgsRasterLayer)
        ]

    def _action(self, text, slot, shortcuts=(), tip="", work_area=True, menu=None, toolbar=None):
        """A QAction calling `slot` (errors to the status bar); shortcuts shown in the menu and tooltip.
        Work-area actions (measuring keys) only react while the focus is in the views or the table, so
        Return, Delete and letters keep working in the editor's fields."""
        action = QAction(text, self)
        keys = [QKeySequence(s) for s in shortcuts]
        action.setShortcuts(keys)
        names = ", ".join(k.toString(QKeySequence.NativeText) for k in keys)
        action.setToolTip(f"{tip or text.replace('&', '').rstrip('.')}" + (f" ({names})" if names else ""))
        action.setStatusTip(action.toolTip())
        action.triggered.connect(lambda _checked=False: self._guarded(slot))
        if work_area:
            action.setShortcutContext(Qt.WidgetWithChildrenShortcut)
            for widget in self.work_area:
                widget.addAction(action)
        if menu is not None:
            menu.addAction(action)
        if toolbar is not None:
            toolbar.addAction(action)
        return action

    def _build_actions(self):
        bar = self.menuBar()
        tools = self.addToolBar("Measurement")
        tools.setObjectName("pushbroom_measurement_toolbar")
        tools.setToolButtonStyle(Qt.ToolButtonTextOnly)
        tools.setMovable(False)
        files = bar.addMenu("&File")
        self._action(
            "Import points CSV...",
            self._ask_import_csv,
            work_area=False,
            menu=files,
            tip="Merge the points of a CSV file (pushbroom:importpoints format) into the block",
        )
        self._action("Export points CSV...", self._ask_export_csv, work_area=False, menu=files)
        files.addSeparator()
        self._action(
            "Import Georeferencer .points...",
            self._ask_import_points,
            work_area=False,
            menu=files,
            tip="Merge the 2-D reference points of a QGIS Georeferencer .points file, measured in one image",
        )
        self._action("Export Georeferencer .points...", self._ask_export_points, work_area=False, menu=files)
        files.addSeparator()
        self._action("Close", self.close, ["Ctrl+W"], work_area=False, menu=files)
        edit = bar.addMenu("&Edit")
        self.undo_action = self.undo_stack.createUndoAction(self, "Undo")
        self.undo_action.setShortcuts(QKeySequence.Undo)
        self.redo_action = self.undo_stack.createRedoAction(self, "Redo")
        self.redo_action.setShortcuts(QKeySequence.Redo)
        for action in (self.undo_action, self.redo_action):
            action.setToolTip(f"{action.text()} ({action.shortcut().toString(QKeySequence.NativeText)})")
            edit.addAction(action)
        point = bar.addMenu("&Point")
        self._action(
            "New point",
            self.new_point,
            ["Ctrl+N"],
            work_area=False,
            menu=point,
            toolbar=tools,
            tip="Start a new control point (click it on the reference or in an image)",
        )
        self._action("Previous point", self.previous_point, ["PgUp"], menu=point, toolbar=tools)
        self._action("Next point", self.next_point, ["PgDown"], menu=point, toolbar=tools)
        point.addSeparator()
        self._action(
            "Accept transfers",
            self.accept_pending,
            ["Return", "Enter"],
            menu=point,
            toolbar=tools,
            tip="Accept the pending LSM transfers of the current point",
        )
        self._action(
            "Reject transfers",
            self.reject_pending,
            ["Delete", "Backspace"],
            menu=point,
            toolbar=tools,
            tip="Reject the pending LSM transfers of the current point",
        )
        self._action("Delete measurement in current image", self.delete_measurement, ["Shift+Delete"], menu=point)
        point.addSeparator()
        self._action(
            "Delete point",
            lambda: self.delete_point(self.session.current),
            ["Ctrl+Delete"],
            work_area=False,
            menu=point,
            tip="Delete the current point and its measurements",
        )
        view = bar.addMenu("&View")
        self._action(
            "Zoom to prediction",
            self.zoom_to_prediction,
            ["Z"],
            menu=view,
            toolbar=tools,
            tip="Centre every image on the current point's measurement or prediction, zoomed in",
        )
        self._action("Next image", lambda: self.next_image(1), ["Tab", "Ctrl+Tab"], menu=view)
        self._action("Previous image", lambda: self.next_image(-1), ["Shift+Tab", "Ctrl+Shift+Tab"], menu=view)
        self._action("Fit images", self.fit_images, ["F"], menu=view)
        self._action("Zoom reference to block", self.reference.zoom_to_block, menu=view, work_area=False)
        block_menu = bar.addMenu("&Block")
        tools.addSeparator()
        self._action(
            "Adjust now",
            self.adjust_now,
            ["F5"],
            work_area=False,
            menu=block_menu,
            toolbar=tools,
            tip="Run the bundle adjustment (pushbroom:bundleadjust) in the background and show its residuals",
        )

    # --- messages ------------------------------------------------------------------------------------------
    def show_message(self, text, level=Qgis.Info, timeout=8000):
        """Status bar text; warnings and errors also in the window's message bar."""
        self.statusBar().showMessage(text, timeout)
        if level in (Qgis.Warning, Qgis.Critical):
            self.message_bar.clearWidgets()
            self.message_bar.pushMessage("Pushbroom", text, level=level, duration=15)

    def _guarded(self, action, *args):
        """Run a GUI action; the engine's errors go to the message bar (no traceback)."""
        try:
            return action(*args)
        except PushbroomError as exc:
            self.show_message(str(exc), Qgis.Warning)
            return None

    # slots of the child widgets' signals: bound methods, which PyQt disconnects when the window is
    # destroyed (a lambda would still run while the children emit during their destruction)
    def _stack_changed(self, _index):
        self.refresh()

    def _view_clicked(self, image_id, col, row):
        self.current_image = image_id
        self._highlight_image()
        self._guarded(self.click_image, image_id, col, row)

    def _accept_clicked(self, image_id):
        self._guarded(self.accept_pending, image_id)

    def _reject_clicked(self, image_id):
        self._guarded(self.reject_pending, image_id)

    def _reference_clicked(self, x, y):
        self._guarded(self.set_ground, x, y)

    def _editor_applied(self, values):
        self._guarded(self.apply_editor, values)

    def _table_selected(self, name):
        self._guarded(self.select_point, name)

    def _progress(self, percent):
        self.progress.setValue(int(percent))

    def _push(self, edit):
        """The session's `record`: its edit, done, onto the undo stack (which redraws the window)."""
        self.undo_stack.push(EditCommand(self.session, edit, self._report))

    def _report(self, text):
        self.show_message(text, Qgis.Warning)

    # --- drawing -----------------------------------------------------------------------------------------
    def refresh(self):
        """Redraw the table, the views and the reference from the session."""
        self.table.set_data(self.session.point_summaries(), self.session.image_names, self.session.current)
        self._redraw()

    def _redraw(self):
        """Markers and residual vectors in the views, points on the reference, editor, status."""
        session = self.session
        current = session.current
        predicted = session.predictions(current) if current is not None else {}
        measured_here = session.measurements(current)
        for image_id, pane in self.panes.items():
            markers, vectors = [], []
            for name, col, row in session.measured_in(image_id):
                markers.append(Marker(col, row, "selected" if name == current else "measurement", name))
                res = session.image_residual(name, image_id)
                if res is not None:
                    vectors.append(Vector(col, row, res[0], res[1], residual_magnitudes(res)[1] > CRITICAL))
            p = predicted.get(image_id)
            if p is not None:
                markers.append(Marker(p[0], p[1], "prediction", "" if image_id in measured_here else current))
            t = session.pending.get(image_id)
            if t is not None:
                markers.append(Marker(t.col, t.row, "transfer", f"{current} rho {t.rho:.2f}"))
            pane.view.set_markers(markers)
            pane.view.set_vectors(vectors)
            pane.set_pending(t is not None)
            text, tip = self._pane_text(image_id, p)
            pane.status.setText(text)
            pane.status.setToolTip(tip)
        self.reference.set_points(session.observations.points, current, residual_px=session.residual_px())
        self._show_editor()
        n, m = len(session.observations.points), len(session.observations.measurements)
        self.point_label.setText(
            f"{n} point{'s' if n != 1 else ''}, {m} measurements" + (f" | current: {current}" if current else "")
        )

    def _pane_text(self, image_id, predicted):
        session = self.session
        name = session.image_names[image_id]
        if session.current is None:
            return name, ""
        ground = session.ground(session.current)
        if ground is not None and ground[3]:
            name += " (provisional)"
        if image_id in session.pending:
            t = session.pending[image_id]
            return f"{name}: rho {t.rho:.2f} (pending)", f"LSM transfer: rho {t.rho:.3f}, sigma {t.sigma_px:.3f} px"
        measured = session.measurements(session.current).get(image_id)
        if measured is not None:
            return f"{name}: measured", f"measured at col {measured[0]:.2f}, row {measured[1]:.2f}"
        if image_id in session.transfer_notes:
            return f"{name}: no transfer", session.transfer_notes[image_id]
        return f"{name}: {'predicted' if predicted is not None else 'outside'}", ""

    def _show_editor(self):
        current = self.session.current
        if current is None:
            self.editor.setEnabled(False)
            self.editor.show_point("", "control", (math.nan,) * 3)
            return
        self.editor.setEnabled(True)
        values = self.session.values(current)
        ground = self.session.ground(current)
        lon, lat, h = ground[:3] if ground is not None else (math.nan,) * 3
        xy = self.reference.from_wgs84(lon, lat) if math.isfinite(lon) else (math.nan, math.nan)
        self.editor.show_point(current, values["role"], [values[k] for k in SIGMA_KEYS], lon, lat, h, xy)

    # --- points -----------------------------------------------------------------------------------------
    def new_point(self, name=None, role="control"):
        """Make a new point current (stored once it gets ground coordinates or a measurement); returns
        its name."""
        name = self.session.new_point(name, role)
        self._show_current()
        self.show_message(f"new point {name}: click it on the reference map or in an image")
        return name

    def _show_current(self):
        self.table.select(self.session.current)
        self._redraw()

    def select_point(self, name):
        """Make stored point `name` current; the views centre on it."""
        self.session.select_point(name)
        self._show_current()
        self.zoom_to_prediction(zoom=None)

    def next_point(self, step=1):
        """Select the next (step -1: previous) point in the table's order."""
        names = self.table.names()
        if not names:
            return
        current = self.session.current
        k = names.index(current) + step if current in names else (0 if step > 0 else -1)
        self.select_point(names[k % len(names)])

    def previous_point(self):
        self.next_point(-1)

    def edit_point(self, name, new_name=None, role=None, sigma_e=None, sigma_n=None, sigma_h=None):
        """Change role and sigmas and rename point `name` (one undo step)."""
        if self.session.edit_point(name, new_name, role, sigma_e, sigma_n, sigma_h):
            self.refresh()

    def apply_editor(self, values):
        """The editor's Apply: name, role, sigmas, and the typed coordinates when they changed."""
        if self.session.current is None:
            self.new_point(values["name"] or None, values["role"])
        self.edit_point(
            self.session.current,
            new_name=values["name"] or None,
            role=values["role"],
            **{k: values[k] for k in SIGMA_KEYS},
        )
        shown = self.editor.shown
        typed = [values[k] for k in ("x", "y", "h")]
        if (
            values["x"] is not None
            and values["y"] is not None
            and (typed != [shown.get(k) for k in ("x", "y", "h")] or values["system"] != shown.get("system"))
        ):
            crs = "EPSG:4326" if values["system"] == "wgs84" else None
            self.set_ground(values["x"], values["y"], crs=crs, h=values["h"])

    def delete_point(self, name):
        """Delete point `name` and its measurements (undo restores them)."""
        if name is None:
            return
        if self.session.delete_point(name):
            self.show_message(f"point {name} deleted (undo: {self.undo_action.shortcut().toString()})")
        else:
            self._show_current()

    # --- ground ------------------------------------------------------------------------------------------
    def set_ground(self, x, y, crs=None, h=None):
        """Set the current point's ground position (a new point if none is current): (x, y) in `crs`
        (default: the reference canvas CRS), h ellipsoidal, from the DEM when None. The predictions are
        marked in every image and the views centre on them."""
        lon, lat = self.reference.to_wgs84(x, y, crs)
        source = "typed"
        if h is None:
            h, source = self.reference.height(lon, lat)
        if self.session.current is None:
            self.new_point()
        self.session.set_ground(lon, lat, h)
        self.refresh()
        self.zoom_to_prediction(zoom=None)
        self.show_message(f"{self.session.current}: lon {lon:.7f}, lat {lat:.7f}, h {h:.2f} m ({source})")

    # --- image measurements --------------------------------------------------------------------------------
    def click_image(self, image_id, col, row, transfer=True):
        """Measure the current point (a new one if none) at (col, row) in image `image_id`; with
        `transfer`, LSM transfers it into the images where it is not measured yet (pending results)."""
        image_id = self.session.check_image(image_id)
        if self.session.current is None:
            self.new_point()
        self.session.measure(image_id, col, row, dem=self.reference.dem)
        if transfer:
            self._transfer(image_id, col, row)
        self.refresh()

    def _transfer(self, image_id, col, row):
        session = self.session
        name = session.current
        results = session.transfer(image_id, col, row)
        for target, t in results.items():
            if t.ok:
                self.image_views[target].center_on(t.col, t.row)
        notes = [f"{session.image_names[target]}: {t.reason}" for target, t in results.items() if not t.ok]
        if session.pending:
            pending = ", ".join(session.image_names[i] for i in session.pending)
            self.show_message(f"{name}: transfers pending in {pending} - accept (Return) or reject (Delete)")
        if notes:
            self.show_message(f"{name}: no transfer into " + "; ".join(notes), Qgis.Warning)

    def accept_pending(self, image_id=None):
        """Store the pending transfers (of `image_id` only, or all)."""
        self.session.accept_pending(image_id)

    def reject_pending(self, image_id=None):
        """Drop the pending transfers (of `image_id` only, or all)."""
        self.session.reject_pending(image_id)
        self._redraw()

    def delete_measurement(self, image_id=None):
        """Delete the current point's measurement in `image_id` (default: the current image)."""
        self.session.delete_measurement(self.current_image if image_id is None else image_id)

    # --- views --------------------------------------------------------------------------------------------
    def zoom_to_prediction(self, zoom=DETAIL_ZOOM):
        """Centre every view on the current point: its measurement, pending transfer or prediction, at
        `zoom` screen px per column (None: the view's zoom, at least DETAIL_ZOOM / 2)."""
        session = self.session
        for image_id, (col, row) in session.current_positions().items():
            view = self.image_views[image_id]
            view.center_on(col, row, zoom if zoom is not None else max(view.zoom, DETAIL_ZOOM / 2))
        ground = session.ground(session.current)
        if ground is not None:
            self.reference.center_on(ground[0], ground[1])

    def fit_images(self):
        for view in self.image_views.values():
            view.fit()

    def next_image(self, step=1):
        """Make the next (step -1: previous) image current: its frame is highlighted and its view focused."""
        ids = list(self.session.image_names)
        k = ids.index(self.current_image) if self.current_image in ids else -step
        self.current_image = ids[(k + step) % len(ids)]
        self._highlight_image()
        self.image_views[self.current_image].setFocus(Qt.ShortcutFocusReason)

    def _highlight_image(self):
        for image_id, pane in self.panes.items():
            pane.set_current(image_id == self.current_image)

    # --- adjustment -------------------------------------------------------------------------------------------
    def adjust_now(self):
        """Run the bundle adjustment in a QgsTask; adjusted(ok, message) when it is done."""
        if not self.runner.start():
            self.show_message("an adjustment is already running")
            return
        self.progress.setValue(0)
        self.progress.show()
        self.show_message("adjusting the block...", timeout=0)

    def _adjust_finished(self, ok, message):
        self.progress.hide()
        if ok:
            self.session.adjusted()
            self.refresh()
            self.show_message(message, Qgis.Success)
        else:
            self.show_message(f"adjustment failed: {message}", Qgis.Critical)
        self.adjusted.emit(ok, message)

    # --- files ------------------------------------------------------------------------------------------------
    def import_csv(self, path, **options):
        """Merge the points of a CSV file (control_points.import_csv options) into the block (undoable)."""
        after = self.session.import_csv(path, **options)
        self.show_message(f"imported {path}: {len(after.points)} points in the block")

    def export_csv(self, path):
        self.session.export_csv(path)
        self.show_message(f"points written to {path}")

    def import_points_file(self, path, image_id):
        """Merge a QGIS Georeferencer .points file measured in image `image_id` (heights from the DEM,
        else the block's mean height; map coordinates without a #CRS line in the canvas CRS; undoable)."""
        read = self.session.import_points_file(
            path, image_id, map_crs=self.reference.crs().toWkt(), dem=self.reference.dem
        )
        self.show_message(
            f"imported {len(read.points)} points of {path} measured in {self.session.image_names[int(image_id)]}"
        )

    def export_points_file(self, path, image_id):
        """Write the points measured in image `image_id` as a QGIS Georeferencer .points file."""
        self.session.export_points_file(path, image_id, crs=self.reference.crs().toWkt())
        self.show_message(f"points of {self.session.image_names[int(image_id)]} written to {path}")

    def _ask_file(self, save, title, filters):
        dialog = QFileDialog.getSaveFileName if save else QFileDialog.getOpenFileName
        path, _ = dialog(self, title, os.path.dirname(self.block_path), filters)
        return path or None

    def _ask_image(self, title):
        names = self.session.image_names
        current = list(names).index(self.current_image) if self.current_image in names else 0
        name, ok = QInputDialog.getItem(
            self, title, "Image of the pixel coordinates", list(names.values()), current, False
        )
        return self.session.image_id(name) if ok else None

    def _ask_import_csv(self):
        path = self._ask_file(False, "Import points CSV", "CSV files (*.csv *.txt);;All files (*)")
        if path:
            self.import_csv(path)

    def _ask_export_csv(self):
        path = self._ask_file(True, "Export points CSV", "CSV files (*.csv)")
        if path:
            self.export_csv(path)

    def _ask_import_points(self):
        image_id = self._ask_image("Import Georeferencer points")
        if image_id is not None:
            path = self._ask_file(False, "Import Georeferencer points", "Georeferencer points (*.points)")
            if path:
                self.import_points_file(path, image_id)

    def _ask_export_points(self):
        image_id = self._ask_image("Export Georeferencer points")
        if image_id is not None:
            path = self._ask_file(True, "Export Georeferencer points", "Georeferencer points (*.points)")
            if path:
                self.export_points_file(path, image_id)
