"""The reference view of the measurement window: a QGIS map canvas with the reference layers
(orthoimages, maps), the block's image footprints and its control/check points, and a DEM for the
heights of clicked points.

A left click without dragging emits clicked(x, y) in the canvas CRS; dragging pans, the wheel zooms.
Heights come from the chosen DEM raster (algorithms.dem.Dem: bilinear, read once; heights taken as
ellipsoidal unless 'EGM96' is ticked, then h = H + N with the EGM96 undulation N), or, without a DEM,
the block's mean terrain height."""

import math
import os

from qgis.core import (
    QgsCoordinateReferenceSystem,
    QgsCoordinateTransform,
    QgsCsException,
    QgsFeature,
    QgsGeometry,
    QgsMapLayerProxyModel,
    QgsPointXY,
    QgsProject,
    QgsRasterLayer,
    QgsVectorLayer,
)
from qgis.gui import QgsMapCanvas, QgsMapLayerComboBox, QgsMapTool, QgsVertexMarker
from qgis.PyQt.QtCore import Qt, pyqtSignal
from qgis.PyQt.QtGui import QColor
from qgis.PyQt.QtWidgets import QCheckBox, QFileDialog, QHBoxLayout, QLabel, QToolButton, QVBoxLayout, QWidget

from ..algorithms.adjustment.control_points import orthometric_to_ellipsoidal
from ..algorithms.block import Block
from ..algorithms.dem_store import read_dem
from ..algorithms.errors import InputError, PushbroomError
from ..resource_files import resource_path

WGS84 = "EPSG:4326"
#: mouse travel (screen px) that turns a click into a pan
DRAG_THRESHOLD = 3


class ClickPanTool(QgsMapTool):
    """Left click: clicked(QgsPointXY in canvas CRS); left drag: pan."""

    clicked = pyqtSignal(QgsPointXY)

    def __init__(self, canvas):
        super().__init__(canvas)
        self.press = None
        self.dragging = False

    def canvasPressEvent(self, event):
        if event.button() == Qt.LeftButton:
            self.press, self.dragging = event.pos(), False

    def canvasMoveEvent(self, event):
        if self.press is None or not event.buttons() & Qt.LeftButton:
            return
        if not self.dragging and (event.pos() - self.press).manhattanLength() > DRAG_THRESHOLD:
            self.dragging = True
        if self.dragging:
            self.canvas().panAction(event)

    def canvasReleaseEvent(self, event):
        if event.button() != Qt.LeftButton or self.press is None:
            return
        if self.dragging:
            self.canvas().panActionEnd(event.pos())
        else:
            self.clicked.emit(self.toMapCoordinates(event.pos()))
        self.press, self.dragging = None, False


def memory_layer(definition, name, qml):
    """A memory layer (not added to the project) styled with resources/styles/`qml`."""
    layer = QgsVectorLayer(definition, name, "memory")
    layer.loadNamedStyle(resource_path("styles", qml))
    return layer


class ReferenceView(QWidget):
    """Map canvas with reference `layers` (QgsMapLayer list), footprints and points of the block;
    DEM from `dem_path` or a raster layer chosen in the DEM box. Signals: clicked(x, y) in the canvas
    CRS, message(text) for the status bar."""

    clicked = pyqtSignal(float, float)
    message = pyqtSignal(str)

    def __init__(self, block_path, layers=(), dem_path=None, default_height=0.0, parent=None):
        super().__init__(parent)
        self.block_path = str(block_path)
        self.layers = list(layers)
        self.default_height = float(default_height)
        self.dem = None
        self.own_layers = []  # raster layers this view opened (DEM files): kept alive here
        self.canvas = QgsMapCanvas(self)
        self.canvas.setCanvasColor(QColor(250, 250, 250))
        self.canvas.setToolTip(
            "Reference: click to set the point's ground position (X, Y from the map, Z from "
            "the DEM); drag to pan, wheel to zoom"
        )
        self.tool = ClickPanTool(self.canvas)
        self.tool.clicked.connect(self._tool_clicked)
        self.canvas.setMapTool(self.tool)
        self.points_layer = memory_layer(
            "PointZ?crs=EPSG:4326&field=name:string(32)&field=role:string(8)&field=residual_px:double",
            "control points",
            "control_points.qml",
        )
        self.footprints_layer = memory_layer(
            "Polygon?crs=EPSG:4326&field=image_id:integer&field=name:string", "footprints", "footprints.qml"
        )
        self._fill_footprints()
        self.marker = QgsVertexMarker(self.canvas)
        self.marker.setIconType(QgsVertexMarker.ICON_BOX)
        self.marker.setColor(QColor(255, 200, 0))
        self.marker.setIconSize(18)
        self.marker.setPenWidth(3)
        self.marker.hide()
        crs = (
            self.layers[0].crs()
            if self.layers
            else QgsCoordinateReferenceSystem(Block(self.block_path).info().get("default_crs", WGS84))
        )
        self.canvas.setDestinationCrs(crs)
        self.canvas.setLayers([self.points_layer, self.footprints_layer] + self.layers)
        self.dem_box = QgsMapLayerComboBox(self)
        self.dem_box.setFilters(QgsMapLayerProxyModel.RasterLayer)
        self.dem_box.setAllowEmptyLayer(True)
        self.dem_box.setToolTip(
            f"DEM for the heights of clicked points (empty: the block's mean height {self.default_height:.0f} m)"
        )
        self.geoid = QCheckBox("EGM96", self)
        self.geoid.setToolTip("The DEM holds orthometric (EGM96) heights, e.g. SRTM: add the geoid undulation")
        browse = QToolButton(self)
        browse.setText("…")
        browse.setToolTip("Open a DEM raster file")
        browse.clicked.connect(self._browse_dem)
        bar = QHBoxLayout()
        bar.setContentsMargins(0, 0, 0, 0)
        bar.addWidget(QLabel("DEM", self))
        bar.addWidget(self.dem_box, 1)
        bar.addWidget(browse)
        bar.addWidget(self.geoid)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        layout.addLayout(bar)
        layout.addWidget(self.canvas, 1)
        self.dem_box.setAdditionalLayers([layer for layer in self.layers if isinstance(layer, QgsRasterLayer)])
        self.dem_box.layerChanged.connect(self._dem_layer_changed)
        if dem_path:
            self.set_dem(dem_path)
        else:
            self.dem_box.setLayer(None)
        self.zoom_to_block()

    def _tool_clicked(self, point):
        self.clicked.emit(point.x(), point.y())

    # coordinates ---------------------------------------------------------------------------------------

    def crs(self):
        """The canvas CRS (typed X/Y and clicks are in it)."""
        return self.canvas.mapSettings().destinationCrs()

    def _transform(self, source, target):
        return QgsCoordinateTransform(source, target, QgsProject.instance())

    def _point(self, source, target, x, y):
        """(x, y) transformed from CRS `source` to `target`; InputError where PROJ cannot."""
        try:
            p = self._transform(source, target).transform(QgsPointXY(float(x), float(y)))
        except QgsCsException as exc:
            raise InputError(
                f"cannot transform ({x}, {y}) from {source.authid() or source.description()} to "
                f"{target.authid()}: {exc}"
            ) from exc
        return p.x(), p.y()

    def to_wgs84(self, x, y, crs=None):
        """(lon, lat) of (x, y) in `crs` (QgsCoordinateReferenceSystem or definition; default: canvas CRS)."""
        if crs is None:
            source = self.crs()
        else:
            source = crs if isinstance(crs, QgsCoordinateReferenceSystem) else QgsCoordinateReferenceSystem(str(crs))
        if not source.isValid():
            raise InputError(f"{crs!r} is no coordinate reference system QGIS knows: give an EPSG code or WKT")
        return self._point(source, QgsCoordinateReferenceSystem(WGS84), x, y)

    def from_wgs84(self, lon, lat):
        """(x, y) in the canvas CRS of WGS 84 (lon, lat)."""
        return self._point(QgsCoordinateReferenceSystem(WGS84), self.crs(), lon, lat)

    # DEM ---------------------------------------------------------------------------------------------

    def set_dem(self, dem):
        """Use `dem` (a raster file path or QgsRasterLayer; None: no DEM) for heights."""
        if dem is None or isinstance(dem, QgsRasterLayer):
            self.dem_box.setLayer(dem)
            return
        layer = QgsRasterLayer(os.fspath(dem), os.path.basename(os.fspath(dem)))
        if not layer.isValid():
            self.message.emit(f"cannot open the DEM {dem}: not a raster GDAL reads")
            return
        self.own_layers.append(layer)
        self.dem_box.setAdditionalLayers(self.dem_box.additionalLayers() + [layer])
        self.dem_box.setLayer(layer)
        self._dem_layer_changed(layer)

    def _browse_dem(self):
        path, _ = QFileDialog.getOpenFileName(
            self, "DEM raster", "", "Rasters (*.tif *.tiff *.vrt *.img *.dem);;All files (*)"
        )
        if path:
            self.set_dem(path)

    def _dem_layer_changed(self, layer):
        if layer is None:
            self.dem = None
            return
        try:
            self.dem = read_dem(layer.source())
        except PushbroomError as exc:
            self.dem = None
            self.message.emit(f"DEM {layer.name()} not used: {exc}")

    def height(self, lon, lat):
        """(h, source text): ellipsoidal height at (lon, lat) from the DEM, else the block's mean height."""
        if self.dem is not None:
            h = self.dem.height(lon, lat)
            if math.isfinite(h):
                if self.geoid.isChecked():
                    return float(orthometric_to_ellipsoidal(lon, lat, h)[0]), "DEM (EGM96 + N)"
                return h, "DEM"
            return self.default_height, "outside the DEM: block mean height"
        return self.default_height, "no DEM: block mean height"

    # drawing -------------------------------------------------------------------------------------------

    def _fill_footprints(self):
        features = []
        for k, (name, wkt) in enumerate(Block(self.block_path).footprints(), start=1):
            feature = QgsFeature(self.footprints_layer.fields())
            feature.setAttributes([k, name])
            feature.setGeometry(QgsGeometry.fromWkt(wkt))
            features.append(feature)
        self.footprints_layer.dataProvider().addFeatures(features)
        self.footprints_layer.updateExtents()

    def zoom_to_block(self):
        """Show the footprints (or the reference layers without any) with a margin."""
        extent = self.footprints_layer.extent()
        if extent.isEmpty() and self.layers:
            extent = self.layers[0].extent()
            transform = self._transform(self.layers[0].crs(), self.crs())
        else:
            transform = self._transform(QgsCoordinateReferenceSystem(WGS84), self.crs())
        if not extent.isEmpty():
            extent = transform.transformBoundingBox(extent)
            extent.scale(1.1)
            self.canvas.setExtent(extent)
            self.canvas.refresh()

    def set_points(self, points, current=None, provisional=None, residual_px=None):
        """Draw `points` (POINT_DTYPE records with ground coordinates; NaN ones are skipped), labelled with
        their image residual RMS (`residual_px` {name: px}), and mark `current` (a point name) or the
        (lon, lat) `provisional` position."""
        residual_px = residual_px or {}
        provider = self.points_layer.dataProvider()
        provider.truncate()
        features, here = [], provisional
        for p in points:
            if not (math.isfinite(p["lon"]) and math.isfinite(p["lat"])):
                continue
            feature = QgsFeature(self.points_layer.fields())
            rms = residual_px.get(str(p["name"]), math.nan)
            feature.setAttributes([str(p["name"]), str(p["role"]), rms if math.isfinite(rms) else None])
            feature.setGeometry(QgsGeometry.fromWkt(f"POINT Z ({p['lon']!r} {p['lat']!r} {p['h']!r})"))
            features.append(feature)
            if str(p["name"]) == current:
                here = (float(p["lon"]), float(p["lat"]))
        provider.addFeatures(features)
        self.points_layer.updateExtents()
        self.points_layer.triggerRepaint()
        if here is None:
            self.marker.hide()
        else:
            self.marker.setCenter(QgsPointXY(*self.from_wgs84(*here)))
            self.marker.show()

    def center_on(self, lon, lat):
        """Centre the canvas on WGS 84 (lon, lat), keeping the scale."""
        self.canvas.setCenter(QgsPointXY(*self.from_wgs84(lon, lat)))
        self.canvas.refresh()
