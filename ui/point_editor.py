"""The point editor of the measurement window: name, role, a priori sigmas E/N/H (m) and typed
ground coordinates, either WGS 84 lon/lat (degrees) or X/Y in the reference canvas CRS, with the
height (ellipsoidal, m; empty: from the DEM). Apply (or Return in a field) emits applied(dict)."""

import math

from qgis.PyQt.QtCore import pyqtSignal
from qgis.PyQt.QtWidgets import QComboBox, QDoubleSpinBox, QFormLayout, QGroupBox, QHBoxLayout, QLineEdit, QPushButton

from ..algorithms.adjustment.control_points import DEFAULT_SIGMAS, ROLES


def _text(value, digits):
    return "" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


class PointEditor(QGroupBox):
    """Fields of one point; `show_point(name, role, sigmas, lon, lat, h, map_xy)` fills them,
    `values()` reads them. `crs_name` labels the map system."""

    applied = pyqtSignal(dict)

    def __init__(self, crs_name, parent=None):
        super().__init__("Point", parent)
        self.name = QLineEdit(self)
        self.name.setMaxLength(32)
        self.name.setToolTip("Point name (unique, at most 32 characters); change it and Apply to rename")
        self.role = QComboBox(self)
        self.role.addItems(ROLES)
        self.sigmas = []
        row = QHBoxLayout()
        for axis, default in zip("ENH", DEFAULT_SIGMAS):
            box = QDoubleSpinBox(self)
            box.setRange(0.001, 1000.0)
            box.setDecimals(3)
            box.setValue(default)
            box.setToolTip(f"A priori standard deviation of the ground {axis} coordinate (m)")
            self.sigmas.append(box)
            row.addWidget(box)
        self.system = QComboBox(self)
        self.system.addItem("WGS 84 lon/lat (deg)", "wgs84")
        self.system.addItem(f"map X/Y ({crs_name})", "map")
        self.system.currentIndexChanged.connect(self._system_changed)
        self.x, self.y, self.h = QLineEdit(self), QLineEdit(self), QLineEdit(self)
        self.h.setPlaceholderText("from the DEM")
        self.h.setToolTip("Ellipsoidal height (m); leave empty to take it from the DEM")
        coords = QHBoxLayout()
        for field, stretch in ((self.x, 3), (self.y, 3), (self.h, 2)):
            coords.addWidget(field, stretch)
            field.returnPressed.connect(self.apply)
        self.name.returnPressed.connect(self.apply)
        self.apply_button = QPushButton("Apply", self)
        self.apply_button.setToolTip("Store the name, role, sigmas and typed coordinates (Return in a field)")
        self.apply_button.clicked.connect(self.apply)
        form = QFormLayout(self)
        form.setContentsMargins(6, 6, 6, 6)
        form.addRow("Name", self.name)
        form.addRow("Role", self.role)
        form.addRow("Sigma E/N/H", row)
        form.addRow("Coordinates", self.system)
        form.addRow("X, Y, h", coords)
        form.addRow(self.apply_button)
        self.shown = {}
        self._lonlat, self._map = (math.nan, math.nan), (math.nan, math.nan)

    def show_point(self, name, role, sigmas, lon=math.nan, lat=math.nan, h=math.nan, map_xy=(math.nan, math.nan)):
        """Fill the fields (NaN coordinates: empty) and remember them to tell typed changes apart."""
        self.name.setText(name or "")
        self.role.setCurrentText(role)
        for box, value in zip(self.sigmas, sigmas):
            box.setValue(value if math.isfinite(value) else box.value())
        self._lonlat, self._map = (lon, lat), tuple(map_xy)
        self._show_xy()
        self.h.setText(_text(h, 3))
        self.shown = self.values()

    def _show_xy(self):
        x, y = self._lonlat if self.system.currentData() == "wgs84" else self._map
        digits = 7 if self.system.currentData() == "wgs84" else 3
        self.x.setText(_text(x, digits))
        self.y.setText(_text(y, digits))

    def _system_changed(self):
        self._show_xy()
        self.shown = self.values()

    def values(self):
        """{name, role, sigma_e, sigma_n, sigma_h, system, x, y, h}: coordinates as typed (None where empty)."""

        def number(field):
            try:
                return float(field.text().replace(",", "."))
            except ValueError:
                return None

        return {
            "name": self.name.text().strip(),
            "role": self.role.currentText(),
            **{f"sigma_{axis}": box.value() for axis, box in zip("enh", self.sigmas)},
            "system": self.system.currentData(),
            "x": number(self.x),
            "y": number(self.y),
            "h": number(self.h),
        }

    def apply(self):
        self.applied.emit(self.values())
