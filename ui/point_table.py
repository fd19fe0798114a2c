"""The point table of the measurement window: one row per control/check point with its height, the
number of images it is measured in, the image residuals |v| (px) and normalised residuals w of the
last adjustment per image, and its ground residuals dE, dN, dH (m); cells coloured by |w| (green
below 2, orange below the critical value 3.29, red above), sortable on every column."""

import math

from qgis.PyQt.QtCore import (
    QAbstractTableModel,
    QItemSelectionModel,
    QModelIndex,
    QSortFilterProxyModel,
    Qt,
    pyqtSignal,
)
from qgis.PyQt.QtGui import QBrush, QColor
from qgis.PyQt.QtWidgets import QAbstractItemView, QHeaderView, QTableView

from ..algorithms.adjustment.bundle import CRITICAL_W

#: |w| limits of the colours: below WARNING green, below CRITICAL (data snooping's default) orange, else red
WARNING, CRITICAL = 2.0, CRITICAL_W
COLOURS = {"good": QColor(200, 240, 200), "warning": QColor(255, 217, 160), "bad": QColor(255, 176, 176)}
SORT_ROLE = Qt.UserRole
BASE_COLUMNS = ["Point", "Role", "h (m)", "Images"]
GROUND_COLUMNS = ["dE (m)", "dN (m)", "dH (m)"]


def grade(w):
    """'good', 'warning' or 'bad' for a normalised residual magnitude |w|."""
    return "good" if w < WARNING else "warning" if w < CRITICAL else "bad"


def _number(value, digits):
    return "" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


class PointTableModel(QAbstractTableModel):
    """The table's data: `set_data(rows, image_names)`, one row per point."""

    def __init__(self, parent=None):
        super().__init__(parent)
        self.image_names = {}
        self.rows = []

    def set_data(self, rows, image_names):
        """rows: MeasurementSession.point_summaries(); image_names {image id: name}."""
        self.beginResetModel()
        self.image_names = dict(image_names)
        self.rows = list(rows)
        self.endResetModel()

    def columns(self):
        """Header texts."""
        per_image = [f"{self.image_names[i]} {what}" for i in self.image_names for what in ("|v|", "|w|")]
        return BASE_COLUMNS + per_image + GROUND_COLUMNS

    def rowCount(self, parent=QModelIndex()):
        return 0 if parent.isValid() else len(self.rows)

    def columnCount(self, parent=QModelIndex()):
        return 0 if parent.isValid() else len(BASE_COLUMNS) + 2 * len(self.image_names) + len(GROUND_COLUMNS)

    def headerData(self, section, orientation, role=Qt.DisplayRole):
        if orientation == Qt.Horizontal and role == Qt.DisplayRole:
            return self.columns()[section]
        if orientation == Qt.Horizontal and role == Qt.ToolTipRole:
            return (
                "|v|: image residual (px) and |w|: largest normalised residual of the last adjustment; "
                f"green |w| < {WARNING}, orange < {CRITICAL}, red above; dE/dN/dH: ground residuals (m)"
            )
        return None

    def cell(self, row, column):
        """(text, sort key, colour grade or None) of a cell."""
        r = self.rows[row]
        n_images = len(self.image_names)
        if column == 0:
            return r["name"], r["name"], None
        if column == 1:
            return r["role"], r["role"], None
        if column == 2:
            return _number(r["h"], 2), _sort_key(r["h"]), None
        if column == 3:
            return str(r["count"]), float(r["count"]), None
        column -= len(BASE_COLUMNS)
        if column < 2 * n_images:
            image_id = list(self.image_names)[column // 2]
            res = r["images"][image_id]
            if res is None:
                return ("-" if image_id in r["measured"] else ""), math.inf, None
            value = res[column % 2]
            return (
                _number(value, 2 if column % 2 == 0 else 1),
                _sort_key(value),
                grade(res[1]) if math.isfinite(res[1]) else None,
            )
        column -= 2 * n_images
        value = r["ground"][column] if r["ground"] is not None else None
        return _number(value, 2), _sort_key(value), None

    def data(self, index, role=Qt.DisplayRole):
        if not index.isValid():
            return None
        text, key, colour = self.cell(index.row(), index.column())
        if role == Qt.DisplayRole:
            return text
        if role == SORT_ROLE:
            return key
        if role == Qt.BackgroundRole and colour is not None:
            return QBrush(COLOURS[colour])
        if role == Qt.TextAlignmentRole and index.column() >= 2:
            return int(Qt.AlignRight | Qt.AlignVCenter)
        return None

    def row_of(self, name):
        """Row of point `name`, or -1."""
        return next((k for k, r in enumerate(self.rows) if r["name"] == name), -1)


def _sort_key(value):
    """Numbers sort by value, missing ones last."""
    return math.inf if value is None or not math.isfinite(value) else float(value)


class PointTable(QTableView):
    """Sortable view of a PointTableModel; selecting a row emits pointSelected(name)."""

    pointSelected = pyqtSignal(str)

    def __init__(self, parent=None):
        super().__init__(parent)
        self.model_ = PointTableModel(self)
        self.proxy = QSortFilterProxyModel(self)
        self.proxy.setSourceModel(self.model_)
        self.proxy.setSortRole(SORT_ROLE)
        self.setModel(self.proxy)
        self.setSortingEnabled(True)
        self.sortByColumn(0, Qt.AscendingOrder)
        self.setSelectionBehavior(QAbstractItemView.SelectRows)
        self.setSelectionMode(QAbstractItemView.SingleSelection)
        self.setEditTriggers(QAbstractItemView.NoEditTriggers)
        self.setAlternatingRowColors(True)
        self.verticalHeader().setVisible(False)
        self.verticalHeader().setDefaultSectionSize(self.fontMetrics().height() + 6)
        self.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeToContents)
        self.selectionModel().currentRowChanged.connect(self._row_changed)
        self._selecting = False

    def set_data(self, rows, image_names, current=None):
        """Fill the table (PointTableModel.set_data) and select `current`."""
        self._selecting = True
        try:
            self.model_.set_data(rows, image_names)
        finally:
            self._selecting = False
        self.select(current)

    def names(self):
        """Point names in the displayed (sorted) order."""
        return [self.proxy.index(k, 0).data() for k in range(self.proxy.rowCount())]

    def select(self, name):
        """Select the row of point `name` (None: clear) without emitting pointSelected."""
        self._selecting = True
        try:
            row = self.model_.row_of(name) if name is not None else -1
            if row < 0:
                self.clearSelection()
                return
            index = self.proxy.mapFromSource(self.model_.index(row, 0))
            self.selectionModel().setCurrentIndex(index, QItemSelectionModel.ClearAndSelect | QItemSelectionModel.Rows)
            self.scrollTo(index)
        finally:
            self._selecting = False

    def _row_changed(self, current, _previous):
        if not self._selecting and current.isValid():
            self.pointSelected.emit(self.proxy.index(current.row(), 0).data())
