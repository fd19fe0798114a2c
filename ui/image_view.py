"""One image of a block in raw sensor geometry: smooth zoom and pan over GDAL overviews (raster_tiles), an
automatic 2-98 % contrast stretch, the 2:1 aspect correction of HRS images, and overlays (markers,
residual vectors, the crosshair of the selected point).

Coordinates are GDAL's: (col, row) = (0, 0) is the top-left corner of the first pixel, its centre (0.5,
0.5). On screen a column is `zoom` pixels wide and a row `zoom * aspect` pixels high. Tiles not yet cached
are read synchronously in paintEvent (256 x 256 from the overview that matches the zoom: a few ms each)."""

import math
from typing import NamedTuple

from qgis.PyQt.QtCore import QPointF, QRectF, Qt, pyqtSignal
from qgis.PyQt.QtGui import QColor, QFont, QImage, QPainter, QPainterPath, QPen
from qgis.PyQt.QtWidgets import QWidget

from ..algorithms.errors import InputError
from .raster_tiles import CACHE_BYTES, ByteLru, Stretch, TileReader

#: default byte bound of the stretched (display) tile images, on top of the reader's tile cache
DISPLAY_CACHE_BYTES = 64 * 2**20
ZOOM_STEP = 1.25  # per wheel notch or +/- key
MAX_ZOOM = 32.0  # screen pixels per image column
DRAG_PX = 4  # a press and release closer than this (Manhattan, screen px) is a click
KEEP_VISIBLE_PX = 32  # panning keeps at least this much of the image in the view
BACKGROUND = QColor(32, 32, 32)


class Marker(NamedTuple):
    """A mark at image position (col, row); kind: "prediction", "measurement", "transfer" or "selected"."""

    col: float
    row: float
    kind: str
    label: str = ""


class Vector(NamedTuple):
    """A residual (dx, dy) in image pixels at (col, row); flagged ones (rejected, blunders) are drawn red."""

    col: float
    row: float
    dx: float
    dy: float
    flagged: bool = False


#: marker kind -> (shape, colour)
MARKER_STYLES = {
    "prediction": ("circle", QColor(0, 220, 255)),
    "measurement": ("cross", QColor(40, 255, 40)),
    "transfer": ("diamond", QColor(255, 170, 0)),
    "selected": ("crosshair", QColor(255, 60, 255)),
}
VECTOR_COLOUR, FLAGGED_COLOUR, OUTLINE = QColor(255, 230, 0), QColor(255, 40, 40), QColor(0, 0, 0)


class ImageView(QWidget):
    """Zoomable, pannable view of one raster; see the module docstring for the coordinates.

    Mouse: wheel zooms around the cursor (x1.25 per notch), a left (or middle) drag pans, a left click
    emits clicked(col, row). Keys: + / = zoom in, - zoom out, arrows pan a quarter of the view."""

    clicked = pyqtSignal(float, float)
    viewChanged = pyqtSignal()

    def __init__(self, parent=None, cache_bytes=CACHE_BYTES, display_cache_bytes=DISPLAY_CACHE_BYTES):
        super().__init__(parent)
        self.reader = None
        self.aspect = 1.0
        self._cache_bytes = cache_bytes
        self._display = ByteLru(display_cache_bytes)
        self._stretch = None
        self._zoom = 1.0
        self._centre = (0.0, 0.0)
        self._fitted = False
        self._markers, self._vectors = [], []
        self._vector_scale = 100.0
        self._title = ""
        self._press = None  # (button, pos, centre, image point) of a left/middle press until its release
        self._dragging = False
        self.setFocusPolicy(Qt.StrongFocus)
        self.setMinimumSize(160, 120)

    # --- image and stretch -------------------------------------------------------------------------
    def open(self, path, aspect=1.0):
        """Show the raster at `path` (aspect = displayed height of a row / width of a column: 0.5 for HRS),
        with the automatic stretch, fitted to the widget."""
        if not aspect > 0:
            raise InputError(f"the aspect (row height / column width on screen) must be > 0, got {aspect}")
        reader = TileReader(path, self._cache_bytes)
        self.clear()
        self.reader, self.aspect = reader, float(aspect)
        self.auto_stretch()
        self.fit()

    def clear(self):
        """Drop the image (its GDAL dataset is closed) and the overlays."""
        if self.reader is not None:
            self.reader.close()
        self.reader, self._stretch = None, None
        self._display.clear()
        self._markers, self._vectors = [], []
        self.update()

    @property
    def path(self):
        return None if self.reader is None else self.reader.path

    @property
    def image_size(self):
        """(cols, rows) of the image, or None."""
        return None if self.reader is None else self.reader.size

    def auto_stretch(self, low=2.0, high=98.0):
        """Stretch between the `low` and `high` percentiles of the image (from a coarse level, see
        TileReader.percentiles); open() sets it once per image."""
        lows, highs = self.reader.percentiles(low, high)
        self._set_stretch(Stretch(lows, highs, self.reader.nodata))

    def set_stretch(self, low, high):
        """Linear stretch: values <= low black, >= high white (scalars, or one per RGB band)."""
        self._set_stretch(Stretch(low, high, None if self.reader is None else self.reader.nodata))

    @property
    def stretch(self):
        """(low, high) arrays, one value per displayed band, or None without an image."""
        return None if self._stretch is None else (self._stretch.low.copy(), self._stretch.high.copy())

    def _set_stretch(self, stretch):
        self._stretch = stretch
        self._display.clear()
        self.update()

    # --- overlays ----------------------------------------------------------------------------------
    def set_markers(self, markers):
        """Replace the markers (a list of Marker)."""
        markers = [Marker(*m) for m in markers]
        unknown = {m.kind for m in markers} - set(MARKER_STYLES)
        if unknown:
            raise InputError(f"unknown marker kind(s) {sorted(unknown)}; use one of {sorted(MARKER_STYLES)}")
        self._markers = markers
        self.update()

    def set_vectors(self, vectors):
        """Replace the residual vectors (a list of Vector)."""
        self._vectors = [Vector(*v) for v in vectors]
        self.update()

    def set_vector_scale(self, scale):
        """A residual of one image pixel is drawn `scale` screen pixels long, whatever the zoom (its row
        component times the aspect)."""
        self._vector_scale = float(scale)
        self.update()

    def title(self, text):
        """Caption drawn in the top-left corner."""
        self._title = str(text)
        self.update()

    # --- geometry ----------------------------------------------------------------------------------
    @property
    def zoom(self):
        """Screen pixels per image column."""
        return self._zoom

    @property
    def view_center(self):
        """(col, row) of the image position at the centre of the widget."""
        return self._centre

    def image_to_widget(self, col, row):
        """Widget position (x, y) of image position (col, row)."""
        return (
            self.width() / 2.0 + (col - self._centre[0]) * self._zoom,
            self.height() / 2.0 + (row - self._centre[1]) * self._zoom * self.aspect,
        )

    def widget_to_image(self, x, y):
        """Image position (col, row) of widget position (x, y)."""
        return (
            self._centre[0] + (x - self.width() / 2.0) / self._zoom,
            self._centre[1] + (y - self.height() / 2.0) / (self._zoom * self.aspect),
        )

    def _fit_zoom(self):
        cols, rows = self.reader.size
        return max(min(self.width() / cols, self.height() / (rows * self.aspect)), 1e-6)  # > 0 in a 0-px widget

    def _zoom_limits(self):
        low = 1.0 / 64 if self.reader is None else min(self._fit_zoom() / 2.0, 1.0)
        return low, MAX_ZOOM

    def _set_view(self, centre, zoom):
        low, high = self._zoom_limits()
        zoom = min(max(float(zoom), low), high)
        if self.reader is not None:
            cols, rows = self.reader.size
            mx = max(self.width() / 2.0 - KEEP_VISIBLE_PX, 0.0) / zoom
            my = max(self.height() / 2.0 - KEEP_VISIBLE_PX, 0.0) / (zoom * self.aspect)
            centre = (min(max(centre[0], -mx), cols + mx), min(max(centre[1], -my), rows + my))
        self._zoom, self._centre = zoom, (float(centre[0]), float(centre[1]))
        self.update()
        self.viewChanged.emit()

    def fit(self):
        """Whole image in the widget, centred (kept fitted on resizes until the next zoom or pan)."""
        if self.reader is None:
            return
        cols, rows = self.reader.size
        self._set_view((cols / 2.0, rows / 2.0), self._fit_zoom())
        self._fitted = True

    def center_on(self, col, row, zoom=None):
        """Put image position (col, row) at the centre of the widget, at `zoom` if given."""
        self._fitted = False
        self._set_view((col, row), self._zoom if zoom is None else zoom)

    def set_zoom(self, zoom, anchor=None):
        """Zoom to `zoom` screen px per column, keeping the image point under widget position `anchor`
        (x, y) where it is (default: the widget centre)."""
        if anchor is None:
            anchor = (self.width() / 2.0, self.height() / 2.0)
        col, row = self.widget_to_image(*anchor)
        low, high = self._zoom_limits()
        zoom = min(max(float(zoom), low), high)
        self._fitted = False
        self._set_view(
            (
                col - (anchor[0] - self.width() / 2.0) / zoom,
                row - (anchor[1] - self.height() / 2.0) / (zoom * self.aspect),
            ),
            zoom,
        )

    def _pan(self, dx, dy):
        """Move the image by (dx, dy) screen pixels."""
        self._fitted = False
        self._set_view(
            (self._centre[0] - dx / self._zoom, self._centre[1] - dy / (self._zoom * self.aspect)), self._zoom
        )

    # --- events ------------------------------------------------------------------------------------
    def _event_point(self, event):
        """Widget position of a mouse event: the centre of the device pixel it names."""
        p = event.localPos()
        half = 0.5 / self.devicePixelRatioF()
        return p.x() + half, p.y() + half

    def wheelEvent(self, event):
        notches = event.angleDelta().y() / 120.0
        if notches and self.reader is not None:
            p = event.position()
            self.set_zoom(self._zoom * ZOOM_STEP**notches, (p.x(), p.y()))
        event.accept()

    def mousePressEvent(self, event):
        if event.button() in (Qt.LeftButton, Qt.MiddleButton):
            self._press = (event.button(), event.pos(), self._centre, self._event_point(event))
            self._dragging = False
        event.accept()

    def mouseMoveEvent(self, event):
        if self._press is None:
            return
        _, start, centre, _ = self._press
        delta = event.pos() - start
        if not self._dragging and delta.manhattanLength() > DRAG_PX:
            self._dragging = True
            self.setCursor(Qt.ClosedHandCursor)
        if self._dragging:
            self._fitted = False
            self._set_view(
                (centre[0] - delta.x() / self._zoom, centre[1] - delta.y() / (self._zoom * self.aspect)), self._zoom
            )

    def mouseReleaseEvent(self, event):
        if self._press is None:
            return
        button, start, _, point = self._press
        if not self._dragging and (event.pos() - start).manhattanLength() > DRAG_PX:
            self.mouseMoveEvent(event)
        clicked = not self._dragging and button == Qt.LeftButton and self.reader is not None
        self._press, self._dragging = None, False
        self.unsetCursor()
        if clicked:
            self.clicked.emit(*self.widget_to_image(*point))

    def keyPressEvent(self, event):
        key = event.key()
        if self.reader is None:
            super().keyPressEvent(event)
        elif key in (Qt.Key_Plus, Qt.Key_Equal):
            self.set_zoom(self._zoom * ZOOM_STEP)
        elif key == Qt.Key_Minus:
            self.set_zoom(self._zoom / ZOOM_STEP)
        elif key in (Qt.Key_Left, Qt.Key_Right):
            self._pan((self.width() / 4.0) * (1 if key == Qt.Key_Left else -1), 0.0)
        elif key in (Qt.Key_Up, Qt.Key_Down):
            self._pan(0.0, (self.height() / 4.0) * (1 if key == Qt.Key_Up else -1))
        else:
            super().keyPressEvent(event)

    def resizeEvent(self, event):
        super().resizeEvent(event)
        if self._fitted:
            self.fit()
        else:
            self.viewChanged.emit()

    # --- painting ----------------------------------------------------------------------------------
    def _display_tile(self, level, tx, ty):
        """Stretched QImage of a tile (cached until the stretch changes)."""
        key = (level, tx, ty)
        image = self._display.get(key)
        if image is None:
            data = self._stretch.apply(self.reader.tile(level, tx, ty))
            h, w = data.shape[:2]
            fmt = QImage.Format_Grayscale8 if data.ndim == 2 else QImage.Format_RGB888
            image = QImage(data.data, w, h, data.strides[0], fmt)
            image.ndarray = data  # the QImage does not own its buffer
            self._display.put(key, image, data.nbytes)
        return image

    def paintEvent(self, event):
        painter = QPainter(self)
        painter.fillRect(self.rect(), BACKGROUND)
        if self.reader is not None:
            self._paint_image(painter)
            painter.setRenderHint(QPainter.Antialiasing, True)
            self._paint_vectors(painter)
            for marker in self._markers:
                self._paint_marker(painter, marker)
        self._paint_caption(painter)
        painter.end()

    def _paint_image(self, painter):
        level = self.reader.level_for(self._zoom, self.aspect)
        lv = self.reader.levels[level]
        minified = min(lv.scale_x * self._zoom, lv.scale_y * self._zoom * self.aspect) < 1.0 - 1e-9
        painter.setRenderHint(QPainter.SmoothPixmapTransform, minified)  # else whole pixels as blocks
        col0, row0 = self.widget_to_image(0.0, 0.0)
        col1, row1 = self.widget_to_image(float(self.width()), float(self.height()))
        tx0, ty0, tx1, ty1 = self.reader.tile_range(level, col0, row0, col1, row1)
        for ty in range(ty0, ty1):
            for tx in range(tx0, tx1):
                c0, r0, c1, r1 = self.reader.tile_bounds(level, tx, ty)
                x0, y0 = self.image_to_widget(c0, r0)
                x1, y1 = self.image_to_widget(c1, r1)
                image = self._display_tile(level, tx, ty)
                painter.drawImage(QRectF(x0, y0, x1 - x0, y1 - y0), image, QRectF(0, 0, image.width(), image.height()))

    def _paint_vectors(self, painter):
        s = self._vector_scale
        for v in self._vectors:
            x, y = self.image_to_widget(v.col, v.row)
            ex, ey = x + v.dx * s, y + v.dy * s * self.aspect
            path = QPainterPath(QPointF(x, y))
            path.lineTo(ex, ey)
            length = math.hypot(ex - x, ey - y)
            if length > 1.0:
                ux, uy = (ex - x) / length, (ey - y) / length
                head = min(6.0, length / 2.0)
                for side in (1.0, -1.0):
                    path.moveTo(ex, ey)
                    path.lineTo(ex - head * (ux - side * 0.5 * uy), ey - head * (uy + side * 0.5 * ux))
            self._stroke(painter, path, FLAGGED_COLOUR if v.flagged else VECTOR_COLOUR)

    def _paint_marker(self, painter, marker):
        shape, colour = MARKER_STYLES[marker.kind]
        x, y = self.image_to_widget(marker.col, marker.row)
        path = QPainterPath()
        if shape == "circle":
            path.addEllipse(QPointF(x, y), 9.0, 9.0)
        elif shape == "diamond":
            path.moveTo(x, y - 9)
            for px, py in ((x + 9, y), (x, y + 9), (x - 9, y), (x, y - 9)):
                path.lineTo(px, py)
        else:
            inner, outer = (3.0, 10.0) if shape == "cross" else (6.0, 28.0)
            for ux, uy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                path.moveTo(x + inner * ux, y + inner * uy)
                path.lineTo(x + outer * ux, y + outer * uy)
        self._stroke(painter, path, colour)
        if marker.label:
            self._text(painter, QPointF(x + 11, y - 11), marker.label, colour)

    @staticmethod
    def _stroke(painter, path, colour):
        """Path in `colour` over a black outline, visible on any image."""
        painter.strokePath(path, QPen(OUTLINE, 4.0, Qt.SolidLine, Qt.RoundCap, Qt.RoundJoin))
        painter.strokePath(path, QPen(colour, 2.0, Qt.SolidLine, Qt.RoundCap, Qt.RoundJoin))

    @staticmethod
    def _text(painter, point, text, colour):
        font = QFont(painter.font())
        font.setBold(True)
        path = QPainterPath()
        path.addText(point, font, text)
        painter.strokePath(path, QPen(OUTLINE, 3.0))
        painter.fillPath(path, colour)

    def _paint_caption(self, painter):
        """The title top left and the zoom (in %) bottom right, on translucent boxes."""
        metrics = painter.fontMetrics()
        captions = []
        if self._title:
            captions.append((4, 4, self._title))
        if self.reader is not None:
            text = f"{self._zoom * 100:.3g} %"
            captions.append(
                (self.width() - metrics.horizontalAdvance(text) - 12, self.height() - metrics.height() - 12, text)
            )
        for x, y, text in captions:
            box = QRectF(x, y, metrics.horizontalAdvance(text) + 8, metrics.height() + 4)
            painter.fillRect(box, QColor(0, 0, 0, 160))
            painter.setPen(QColor(255, 255, 255))
            painter.drawText(box, Qt.AlignCenter, text)
