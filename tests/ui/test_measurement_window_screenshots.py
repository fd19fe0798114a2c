"""Screenshots of the measurement window at 1280 x 800 (tests/output/, not committed): predictions of a
new point set on the reference, then, after 'adjust now' on the simulator's points, a measured point
with its pending LSM transfers and the residual vectors. The PNGs have the window's size and every
view keeps a usable size."""

import pathlib
import shutil

from qgis.core import QgsRasterLayer
from qgis.PyQt.QtGui import QImage

from pushbroom.ui.measurement_window import MeasurementWindow

OUTPUT = pathlib.Path(__file__).resolve().parents[1] / "output"
SIZE = (1280, 800)
MIN_VIEW = 200


def grab(qtbot, window, name):
    """Wait for the reference canvas to render, then save the window as tests/output/<name>."""
    canvas = window.reference.canvas
    canvas.refreshAllLayers()
    qtbot.waitUntil(lambda: not canvas.isDrawing(), timeout=20000)
    canvas.waitWhileRendering()
    qtbot.wait(200)
    OUTPUT.mkdir(exist_ok=True)
    path = OUTPUT / name
    assert window.grab().save(str(path))
    image = QImage(str(path))
    assert (image.width(), image.height()) == SIZE
    return path


def test_screenshots(qtbot, pushbroom_provider, marked_block, marked_scene, tmp_path):
    path = tmp_path / "block.gpkg"
    shutil.copy(marked_block, path)
    window = MeasurementWindow(
        str(path), reference_layers=[QgsRasterLayer(marked_scene["orthoimage"], "ortho")], dem_path=marked_scene["dsm"]
    )
    qtbot.addWidget(window)
    try:
        window.resize(*SIZE)
        window.show()
        qtbot.waitExposed(window)
        for view in list(window.image_views.values()) + [window.reference.canvas]:
            assert view.width() >= MIN_VIEW and view.height() >= MIN_VIEW
        window.import_csv(marked_scene["points"], suffix="_meas")
        window.new_point("NEW")
        window.set_ground(-84.1905, 36.6205)
        grab(qtbot, window, "measurement_window_predictions.png")

        with qtbot.waitSignal(window.adjusted, timeout=180000) as signal:
            window.adjust_now()
        assert signal.args[0], signal.args[1]
        window.delete_point("NEW")
        window.select_point("P004")
        window.delete_measurement(window.session.image_id("HRS1"))
        window.delete_measurement(window.session.image_id("HRS2"))
        measured = window.session.measurements("P004")[window.session.image_id("HRG")]
        window.click_image(window.session.image_id("HRG"), measured[0], measured[1])
        assert len(window.session.pending) == 2
        for view in window.image_views.values():
            assert view._vectors and view.width() >= MIN_VIEW
        window.fit_images()
        grab(qtbot, window, "measurement_window_residuals.png")
        window.zoom_to_prediction()
        grab(qtbot, window, "measurement_window_transfers.png")
    finally:
        for view in window.image_views.values():
            view.clear()
