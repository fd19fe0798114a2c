"""The measurement window driven like a user on the small simulated SPOT 5 triplet with marked points
(tests/conftest.py; pytest-qt, offscreen): a real click on the reference canvas (XY from the map, Z
from the scene's DSM against a numpy bilinear lookup), predictions marked in the views, a real click
in an image with its pending transfers marked and rejected, the panes' texts, undo failures and errors
as messages, the table (contents, colours, sorting, selection), keyboard shortcuts, 'adjust now' in a
QgsTask with its residuals and the File menu. The session's state and edits themselves are tested
without Qt in tests/algorithms/measurement/test_measurement_session.py."""

import math
import shutil

import numpy as np
import pytest
from osgeo import osr
from qgis.core import QgsApplication, QgsPointXY, QgsRasterLayer
from qgis.PyQt.QtCore import QPoint, Qt, QTimer

import pushbroom
from pushbroom.algorithms.adjustment.control_points import DEFAULT_SIGMAS
from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError, PushbroomError
from pushbroom.ui import adjust_task, measurement_window as mw
from pushbroom.ui.point_table import COLOURS, SORT_ROLE
from tests.helpers.osr_oracle import utm
from tests.helpers.raster_oracle import bilinear

#: transfers must land this close (px) to the simulator's true positions
TRANSFER_TOLERANCE = 0.3


@pytest.fixture
def open_window(qtbot, marked_scene):
    """open_window(block, **options): a shown 1280 x 800 MeasurementWindow (reference: the scene's
    orthoimage, DEM: its DSM, unless options say otherwise); its images are closed afterwards."""
    windows = []

    def make(path, **options):
        if "reference_layers" not in options:
            options["reference_layers"] = [QgsRasterLayer(marked_scene["orthoimage"], "orthoimage")]
        options.setdefault("dem_path", marked_scene["dsm"])
        window = mw.MeasurementWindow(path, **options)
        qtbot.addWidget(window)
        window.resize(1280, 800)
        window.show()
        qtbot.waitExposed(window)
        windows.append(window)
        return window

    yield make
    for window in windows:
        for view in window.image_views.values():
            view.clear()


def ids_by_name(window):
    return {name: i for i, name in window.session.image_names.items()}


def stored(path):
    """{name: (point record, {image id: (col, row)})} of the block."""
    obs = Block(path).measurement_store().load()
    out = {}
    for k, p in enumerate(obs.points):
        m = obs.measurements[obs.measurements["point"] == k]
        out[str(p["name"])] = (p, {int(r["image_id"]): (float(r["col"]), float(r["row"])) for r in m})
    return out


def click_canvas(qtbot, canvas, x, y):
    """A real left click on the canvas viewport at the pixel of map coordinate (x, y); returns the
    map coordinate of that pixel."""
    transform = canvas.getCoordinateTransform()
    pixel = transform.transform(QgsPointXY(x, y))
    pos = QPoint(round(pixel.x()), round(pixel.y()))
    clicked = transform.toMapCoordinates(pos)
    qtbot.mouseClick(canvas.viewport(), Qt.LeftButton, pos=pos)
    return clicked


def test_layout_views_and_aspect(open_window, block_path):
    """One view per block image, titled with its name, HRS shown with the 2:1 correction; at 1280 x 800
    no view is narrower than 200 px, the reference canvas and the table have room."""
    window = open_window(block_path)
    names = {r["id"]: r["name"] for r in Block(block_path).images()}
    assert window.session.image_names == names and set(window.image_views) == set(names)
    h = np.mean(Block(block_path).height_range())
    for image_id, view in window.image_views.items():  # ground size of a row / of a column, through OSR's UTM
        model = Block(block_path).model(image_id)
        c, r = 0.5 * np.array(model.size)
        lon, lat = model.image_to_ground(np.array([c, c + 1, c]), np.array([r, r, r + 1]), np.full(3, h))
        x, y = utm(lon, lat, 32616)
        column, row = (math.hypot(x[k] - x[0], y[k] - y[0]) for k in (1, 2))
        assert view.aspect == pytest.approx(row / column, rel=1e-3)
    aspects = {names[i]: view.aspect for i, view in window.image_views.items()}
    assert 0.95 < aspects["HRG"] < 1.05 and 0.45 < aspects["HRS1"] < 0.6 and 0.45 < aspects["HRS2"] < 0.6
    for image_id, view in window.image_views.items():
        assert view.width() >= 200 and view.height() >= 200, (names[image_id], view.size())
        assert names[image_id] in window.panes[image_id].status.text()
    assert window.reference.canvas.width() >= 200 and window.reference.canvas.height() >= 200
    assert window.table.height() >= 120 and window.table.width() >= 600
    assert window.width() == 1280 and window.height() == 800


def test_reference_click_sets_ground_and_predictions(qtbot, open_window, block_path, marked_scene, marked_points):
    """New point, a real click on the canvas: stored lon/lat = the clicked pixel's map coordinate
    (canvas in the orthoimage's EPSG:4326), h = the DSM's bilinear height there; predictions in every
    image = the block model's ground_to_image, marked and centred in the views."""
    window = open_window(block_path)
    canvas = window.reference.canvas
    assert canvas.mapSettings().destinationCrs().authid() == "EPSG:4326"
    name = window.new_point()
    p = marked_points["P003"]
    expected = click_canvas(qtbot, canvas, p["lon"], p["lat"])
    record, meas = stored(block_path)[name]
    assert meas == {}
    assert (record["lon"], record["lat"]) == pytest.approx((expected.x(), expected.y()), abs=1e-9)
    pixel = canvas.mapUnitsPerPixel()
    assert abs(record["lon"] - p["lon"]) < pixel and abs(record["lat"] - p["lat"]) < pixel
    assert record["h"] == pytest.approx(bilinear(marked_scene["dsm"], record["lon"], record["lat"]), abs=1e-6)
    assert record["role"] == "control"
    assert [record[k] for k in ("sigma_e", "sigma_n", "sigma_h")] == list(DEFAULT_SIGMAS)
    for image_id, view in window.image_views.items():
        model = Block(block_path).model(image_id)
        col, row = model.ground_to_image(record["lon"], record["lat"], record["h"])
        predictions = [m for m in view._markers if m.kind == "prediction"]
        assert len(predictions) == 1
        assert (predictions[0].col, predictions[0].row) == pytest.approx((float(col), float(row)), abs=1e-9)
        assert view.view_center == pytest.approx((float(col), float(row)), abs=1e-6)  # the view jumped there
    assert window.session.current == name


def test_reference_click_in_a_projected_canvas(qtbot, open_window, block_path, marked_points):
    """Without reference layers the canvas is in the block's UTM zone: the stored lon/lat is the clicked
    map coordinate converted by OSR (independently)."""
    window = open_window(block_path, reference_layers=[])
    crs = window.reference.crs().authid()
    assert crs == Block(block_path).info()["default_crs"] and crs.startswith("EPSG:326")
    source, target = osr.SpatialReference(), osr.SpatialReference()
    source.ImportFromEPSG(int(crs.split(":")[1]))
    target.ImportFromEPSG(4326)
    for s in (source, target):
        s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    forward = osr.CoordinateTransformation(target, source)
    x, y, _ = forward.TransformPoint(marked_points["P002"]["lon"], marked_points["P002"]["lat"])
    window.new_point("GCP_A")
    clicked = click_canvas(qtbot, window.reference.canvas, x, y)
    lon, lat, _ = osr.CoordinateTransformation(source, target).TransformPoint(clicked.x(), clicked.y())
    record, _ = stored(block_path)["GCP_A"]
    assert (record["lon"], record["lat"]) == pytest.approx((lon, lat), abs=1e-9)


def test_typed_coordinates(open_window, block_path, marked_scene, marked_points):
    """The editor's typed coordinates: X/Y in the canvas CRS (the block's UTM zone) with h from the DEM,
    then WGS 84 lon/lat with a typed h; Apply stores them (and a new name renames the point)."""
    window = open_window(block_path, reference_layers=[])
    epsg = int(window.reference.crs().authid().split(":")[1])
    p = marked_points["P007"]
    (x,), (y,) = utm([p["lon"]], [p["lat"]], epsg)
    window.new_point("T1")
    editor = window.editor
    editor.system.setCurrentIndex(editor.system.findData("map"))
    editor.x.setText(f"{x:.3f}")
    editor.y.setText(f"{y:.3f}")
    editor.h.clear()
    editor.apply_button.click()
    record, _ = stored(block_path)["T1"]
    (xs,), (ys,) = utm([record["lon"]], [record["lat"]], epsg)
    assert (xs, ys) == pytest.approx((round(x, 3), round(y, 3)), abs=1e-6)
    assert record["h"] == pytest.approx(bilinear(marked_scene["dsm"], record["lon"], record["lat"]), abs=1e-6)
    assert editor.x.text() == f"{x:.3f}"
    editor.system.setCurrentIndex(editor.system.findData("wgs84"))
    assert editor.x.text() == f"{record['lon']:.7f}"
    editor.x.setText("-84.1912345")
    editor.y.setText("36.6123456")
    editor.h.setText("301.5")
    editor.name.setText("T2")
    editor.y.returnPressed.emit()
    record, _ = stored(block_path)["T2"]
    assert (record["lon"], record["lat"], record["h"]) == (-84.1912345, 36.6123456, 301.5)
    assert set(stored(block_path)) == {"T2"} and window.session.current == "T2"


def test_reject_and_image_click(qtbot, open_window, block_path, marked_points):
    """A real mouse click in the HRG view measures the image position under the cursor; the pending
    transfers are marked with their rho in their views; rejecting drops them without storing them."""
    window = open_window(block_path)
    ids = ids_by_name(window)
    p = marked_points["P002"]
    window.new_point("P002")
    window.set_ground(p["lon"], p["lat"], crs="EPSG:4326", h=p["h"])
    view = window.image_views[ids["HRG"]]
    view.center_on(p["HRG_col"], p["HRG_row"], 4.0)
    x, y = view.image_to_widget(p["HRG_col"], p["HRG_row"])
    col, row = view.widget_to_image(int(x) + 0.5, int(y) + 0.5)  # the centre of the clicked screen pixel
    qtbot.mouseClick(view, Qt.LeftButton, pos=QPoint(int(x), int(y)))
    meas = stored(block_path)["P002"][1]
    assert meas == {ids["HRG"]: pytest.approx((col, row), abs=1e-9)}
    assert abs(col - p["HRG_col"]) < 0.2 and abs(row - p["HRG_row"]) < 0.2
    assert window.current_image == ids["HRG"]
    assert set(window.session.pending) == {ids["HRS1"], ids["HRS2"]}
    for name in ("HRS1", "HRS2"):
        t = window.session.pending[ids[name]]
        markers = [m for m in window.image_views[ids[name]]._markers if m.kind == "transfer"]
        assert len(markers) == 1 and (markers[0].col, markers[0].row) == (t.col, t.row)
        assert f"rho {t.rho:.2f}" in markers[0].label
        assert window.panes[ids[name]].status.text() == f"{name}: rho {t.rho:.2f} (pending)"
    window.reject_pending(ids["HRS2"])
    assert set(window.session.pending) == {ids["HRS1"]}
    window.reject_pending()
    assert window.session.pending == {} and set(stored(block_path)["P002"][1]) == {ids["HRG"]}


def test_image_first_point_is_provisional(open_window, block_path, marked_points):
    """A point measured in an image before it has ground coordinates: the panes say it is provisional
    and where it is measured."""
    window = open_window(block_path)
    ids = ids_by_name(window)
    p = marked_points["P005"]
    name = window.new_point()
    window.click_image(ids["HRG"], p["HRG_col"], p["HRG_row"], transfer=False)
    assert set(stored(block_path)[name][1]) == {ids["HRG"]}
    assert window.panes[ids["HRG"]].status.text() == "HRG (provisional): measured"
    assert window.panes[ids["HRS1"]].status.text() == "HRS1 (provisional): predicted"


def test_failed_undo_is_a_message(open_window, block_path, marked_points):
    """An undo the block refuses (the point was deleted behind the window's back) is a warning, and the
    undo step is dropped."""
    window = open_window(block_path)
    p = marked_points["P001"]
    window.new_point("A")
    window.set_ground(p["lon"], p["lat"], crs="EPSG:4326", h=p["h"])
    assert window.undo_stack.count() == 1
    Block(block_path).measurement_store().delete_point("A")
    window.undo_stack.undo()
    assert "cannot new point a: the block has no point 'A'" in window.statusBar().currentMessage()
    assert window.undo_stack.count() == 0 and window.session.current is None


def test_errors_go_to_the_status_bar(open_window, block_path, marked_points):
    """A refused edit raises the engine's error in scripting, changes nothing and pushes no undo step;
    from the GUI it is a message, not a traceback."""
    window = open_window(block_path)
    p = marked_points["P001"]
    for name in ("A", "B"):
        window.new_point(name)
        window.set_ground(p["lon"], p["lat"], crs="EPSG:4326", h=p["h"])
    steps = window.undo_stack.count()
    with pytest.raises(InputError, match="exists already"):
        window.edit_point("B", new_name="A")
    assert window.undo_stack.count() == steps and set(stored(block_path)) == {"A", "B"}
    with pytest.raises(InputError, match="no coordinate reference system"):
        window.set_ground(1.0, 2.0, crs="EPSG:999999")
    assert window.undo_stack.count() == steps
    window.editor.name.setText("A")
    window.editor.apply()
    assert "exists already" in window.statusBar().currentMessage()
    assert set(stored(block_path)) == {"A", "B"}


def test_table_contents_sorting_and_selection(qtbot, open_window, block_path, marked_scene, marked_points):
    """Imported simulator points: one row per point with its h and number of images; sorting by h
    orders the rows by height; selecting a row makes its point current and centres the views."""
    window = open_window(block_path)
    window.import_csv(marked_scene["points"], suffix="_meas")
    table, proxy = window.table, window.table.proxy
    assert proxy.rowCount() == len(marked_points)
    headers = [proxy.headerData(c, Qt.Horizontal) for c in range(proxy.columnCount())]
    assert headers[:4] == ["Point", "Role", "h (m)", "Images"] and "HRS1 |v|" in headers and "dH (m)" in headers
    rows = {proxy.index(r, 0).data(): [proxy.index(r, c).data() for c in range(4)] for r in range(proxy.rowCount())}
    for name, p in marked_points.items():
        assert rows[name] == [name, "control", f"{p['h']:.2f}", "3"]
    h_column = headers.index("h (m)")
    table.sortByColumn(h_column, Qt.DescendingOrder)
    assert table.names() == sorted(marked_points, key=lambda n: -marked_points[n]["h"])
    assert proxy.index(0, h_column).data(SORT_ROLE) == max(p["h"] for p in marked_points.values())
    name = table.names()[2]
    table.selectRow(2)
    assert window.session.current == name
    ids = ids_by_name(window)
    p = marked_points[name]
    assert window.image_views[ids["HRG"]].view_center == pytest.approx((p["HRG_col_meas"], p["HRG_row_meas"]))
    window.next_point()  # PgDown order = the table's sorted order
    assert window.session.current == table.names()[3]
    undo_steps = window.undo_stack.count()
    window.undo_stack.undo()  # the import
    assert stored(block_path) == {} and proxy.rowCount() == 0
    window.undo_stack.redo()
    assert len(stored(block_path)) == len(marked_points) and window.undo_stack.count() == undo_steps


def test_keyboard_shortcuts(qtbot, open_window, block_path, marked_scene, marked_points):
    """PgDown/PgUp walk the points, Z zooms to the point, Tab moves to the next image, Return accepts
    and Delete rejects pending transfers, Ctrl+Z/Ctrl+Shift+Z undo and redo, Ctrl+N starts a point;
    the menus show the keys."""
    window = open_window(block_path)
    ids = ids_by_name(window)
    window.import_csv(marked_scene["points"], suffix="_meas")
    view = window.image_views[ids["HRG"]]
    view.setFocus()
    qtbot.waitUntil(view.hasFocus)
    names = window.table.names()
    qtbot.keyClick(view, Qt.Key_PageDown)
    assert window.session.current == names[0]
    qtbot.keyClick(view, Qt.Key_PageDown)
    qtbot.keyClick(view, Qt.Key_PageUp)
    assert window.session.current == names[0]
    view.fit()
    qtbot.keyClick(view, Qt.Key_Z)
    assert view.zoom == mw.DETAIL_ZOOM
    qtbot.keyClick(view, Qt.Key_Tab)
    assert window.current_image == list(window.session.image_names)[1]
    qtbot.keyClick(window.image_views[window.current_image], Qt.Key_Tab)
    qtbot.keyClick(window.image_views[window.current_image], Qt.Key_Tab)
    assert window.current_image == ids["HRG"] and view.hasFocus()
    qtbot.keyClick(view, Qt.Key_N, Qt.ControlModifier)
    name = window.session.current
    assert name not in names
    p = marked_points[names[0]]
    window.set_ground(p["lon"], p["lat"], crs="EPSG:4326", h=p["h"])
    window.click_image(ids["HRG"], p["HRG_col"], p["HRG_row"])
    assert len(window.session.pending) == 2
    view.setFocus()
    qtbot.keyClick(view, Qt.Key_Delete)
    assert window.session.pending == {}
    window.click_image(ids["HRG"], p["HRG_col"], p["HRG_row"])
    window.editor.name.setFocus()
    qtbot.waitUntil(window.editor.name.hasFocus)
    for key in (Qt.Key_Return, Qt.Key_Delete, Qt.Key_Z):  # the editor's fields keep their keys
        qtbot.keyClick(window.editor.name, key)
    assert len(window.session.pending) == 2 and window.editor.name.text() == name + "z"
    window.editor.name.setText(name)
    view.setFocus()
    qtbot.keyClick(view, Qt.Key_Return)
    assert window.session.pending == {} and len(stored(block_path)[name][1]) == 3
    qtbot.keyClick(view, Qt.Key_Z, Qt.ControlModifier)
    assert len(stored(block_path)[name][1]) == 1
    qtbot.keyClick(view, Qt.Key_Z, Qt.ControlModifier | Qt.ShiftModifier)
    assert len(stored(block_path)[name][1]) == 3
    texts = {
        a.text(): a.toolTip()
        for menu in window.menuBar().findChildren(type(window.menuBar().actions()[0].menu()))
        for a in menu.actions()
    }
    assert (
        "PgDown" in texts["Next point"]
        and "Return" in texts["Accept transfers"]
        and "Z" in texts["Zoom to prediction"]
        and "Ctrl+N" in texts["New point"]
        and "Tab" in texts["Next image"]
    )


def test_adjust_now_refreshes_residuals(
    qtbot, pushbroom_provider, open_window, block_path, marked_scene, marked_points
):
    """'Adjust now' on the imported simulator points runs in a QgsTask (the window keeps processing
    events), then the table shows each point's image residuals and w colours, the views draw residual
    vectors from the measurements, and the predictions come from the adjusted models."""
    window = open_window(block_path)
    ids = ids_by_name(window)
    window.import_csv(marked_scene["points"], suffix="_meas")
    blunder = marked_points["P006"]
    window.select_point("P006")
    window.click_image(ids["HRS2"], blunder["HRS2_col_meas"] + 20.0, blunder["HRS2_row_meas"], transfer=False)
    window.select_point("P001")
    before = dict(window.session.predictions("P001"))
    ticks = []
    timer = QTimer()
    timer.timeout.connect(lambda: ticks.append(1))
    timer.start(20)
    with qtbot.waitSignal(window.adjusted, timeout=180000) as signal:
        window.adjust_now()
    ok, message = signal.args
    assert ok, message
    assert len(ticks) > 1  # the event loop ran while the task adjusted
    models = {i: Block(block_path).model(i) for i in window.session.image_names}
    p = marked_points["P001"]
    after = window.session.predictions("P001")
    for image_id, model in models.items():
        col, row = model.ground_to_image(p["lon"], p["lat"], p["h"])
        assert after[image_id] == pytest.approx((float(col), float(row)), abs=1e-9)
        assert after[image_id] != before[image_id]
    proxy = window.table.proxy
    headers = [proxy.headerData(c, Qt.Horizontal) for c in range(proxy.columnCount())]
    image_res, ground = window.session.residuals
    assert set(ground) == set(marked_points)
    column = headers.index("HRS1 |v|")
    for r in range(proxy.rowCount()):
        name = proxy.index(r, 0).data()
        vx, vy, wx, wy = image_res[(name, ids["HRS1"])]
        assert float(proxy.index(r, column).data()) == pytest.approx(math.hypot(vx, vy), abs=0.006)
        w = max(abs(wx), abs(wy))
        colour = "good" if w < 2 else "warning" if w < 3.29 else "bad"
        assert proxy.index(r, column + 1).data(Qt.BackgroundRole).color() == COLOURS[colour]
        assert proxy.index(r, headers.index("dH (m)")).data() == f"{ground[name][2]:.2f}"
    for image_id, view in window.image_views.items():
        name = window.session.image_names[image_id]
        assert len(view._vectors) == len(marked_points)
        v = next(
            v
            for v in view._vectors
            if (v.col, v.row) == (marked_points["P002"][f"{name}_col_meas"], marked_points["P002"][f"{name}_row_meas"])
        )
        assert (v.dx, v.dy) == pytest.approx(image_res[("P002", image_id)][:2])
        by_position = {(m.col, m.row): m.label for m in view._markers}
        for v in view._vectors:  # flagged (red) exactly where |w| exceeds the critical value
            vx, vy, wx, wy = image_res[(by_position[(v.col, v.row)], image_id)]
            assert (v.dx, v.dy) == (vx, vy) and v.flagged == (max(abs(wx), abs(wy)) > 3.29)
    flagged = [v for v in window.image_views[ids["HRS2"]]._vectors if v.flagged]  # the 20 px blunder
    assert (blunder["HRS2_col_meas"] + 20.0, blunder["HRS2_row_meas"]) in [(v.col, v.row) for v in flagged]
    assert (
        proxy.index(window.table.names().index("P006"), headers.index("HRS2 |w|")).data(Qt.BackgroundRole).color()
        == COLOURS["bad"]
    )


def test_adjust_through_the_processing_registry(
    qtbot, qgis_processing, qgis_iface, open_window, block_path, marked_scene
):
    """'Adjust now' runs the registry's pushbroom:bundleadjust, which the plugin's provider registers;
    without the provider it fails with a message that says to enable the plugin."""
    window = open_window(block_path)
    window.import_csv(marked_scene["points"], suffix="_meas")
    with pytest.raises(PushbroomError, match="enable the Pushbroom plugin"):
        adjust_task.bundle_adjust_algorithm()
    with qtbot.waitSignal(window.adjusted, timeout=10000) as signal:
        window.adjust_now()
    ok, message = signal.args
    assert not ok and "enable the Pushbroom plugin" in message
    assert not window.progress.isVisible()
    plugin = pushbroom.classFactory(qgis_iface)
    plugin.initProcessing()
    try:
        registered = QgsApplication.processingRegistry().algorithmById(adjust_task.ALGORITHM)
        assert registered is not None and adjust_task.bundle_adjust_algorithm() is registered
        with qtbot.waitSignal(window.adjusted, timeout=180000) as signal:
            window.adjust_now()
        assert signal.args[0], signal.args[1]
        assert set(window.session.residuals[1]) == set(window.table.names())
        log = [r["step"] for r in Block(block_path).run_log()]
        assert log[-1] == "bundleadjust"
    finally:
        plugin.unload()


def test_adjust_failure_is_a_message(qtbot, pushbroom_provider, open_window, block_path, marked_points):
    """A block without control points: the adjustment fails with the engine's message in the status bar,
    the message bar and the adjusted signal, no traceback; the models stay as they were."""
    window = open_window(block_path)
    ids = ids_by_name(window)
    p = marked_points["P001"]
    before = {i: Block(block_path).model(i).ground_to_image(p["lon"], p["lat"], p["h"]) for i in ids.values()}
    with qtbot.waitSignal(window.adjusted, timeout=120000) as signal:
        window.adjust_now()
    ok, message = signal.args
    assert not ok and "no control points" in message and "Traceback" not in message
    assert message in window.statusBar().currentMessage()
    assert window.message_bar.currentItem() is not None and message in window.message_bar.currentItem().text()
    for i in ids.values():
        assert Block(block_path).model(i).ground_to_image(p["lon"], p["lat"], p["h"]) == before[i]
    assert not window.progress.isVisible()


def test_file_menu_actions(open_window, block_path, marked_scene, marked_block, tmp_path, monkeypatch):
    """The File menu's actions ask for the file (and the image) and call the scripting methods; a bad file
    is a message, not a traceback."""
    window = open_window(block_path)
    window.import_csv(marked_scene["points"], suffix="_meas")
    actions = {a.text(): a for a in window.menuBar().actions()[0].menu().actions()}
    answers = {"save": str(tmp_path / "hrs2.points"), "open": str(tmp_path / "hrs2.points")}
    monkeypatch.setattr(mw.QFileDialog, "getSaveFileName", lambda *args: (answers["save"], ""))
    monkeypatch.setattr(mw.QFileDialog, "getOpenFileName", lambda *args: (answers["open"], ""))
    monkeypatch.setattr(mw.QInputDialog, "getItem", lambda *args: ("HRS2", True))
    actions["Export Georeferencer .points..."].trigger()
    assert open(answers["save"]).read().count(",1,0,0,0") == len(window.table.names())
    answers["save"] = str(tmp_path / "all.csv")
    actions["Export points CSV..."].trigger()
    second = open_window(str(shutil.copy(marked_block, tmp_path / "other.gpkg")))
    second_actions = {a.text(): a for a in second.menuBar().actions()[0].menu().actions()}
    second_actions["Import Georeferencer .points..."].trigger()
    assert len(second.table.names()) == len(window.table.names())
    answers["open"] = str(tmp_path / "all.csv")
    second_actions["Import points CSV..."].trigger()
    assert len(stored(second.block_path)) == 2 * len(window.table.names())  # hrs2_1.. and P001..
    answers["open"] = str(tmp_path / "missing.points")
    second_actions["Import Georeferencer .points..."].trigger()
    assert "cannot read" in second.statusBar().currentMessage()
