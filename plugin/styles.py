"""Styling of the layers Processing loads on completion (QML files in resources/styles)."""

from qgis.core import QgsPointCloudLayer, QgsProcessingContext, QgsProcessingLayerPostProcessorInterface

from ..resource_files import resource_path

# Post-processors must outlive the algorithm run that created them (Processing keeps only a pointer).
_KEEP_ALIVE = []


class ApplyStyle(QgsProcessingLayerPostProcessorInterface):
    """Loads a QML style onto the output layer once QGIS has loaded it."""

    def __init__(self, qml_name):
        super().__init__()
        self.qml = resource_path("styles", qml_name)

    def postProcessLayer(self, layer, context, feedback):
        layer.loadNamedStyle(self.qml)
        layer.triggerRepaint()


def _post_processor(qml_name):
    post = ApplyStyle(qml_name)
    _KEEP_ALIVE.append(post)
    return post


def load_styled(context, source, name, output_name, qml_name):
    """Ask Processing to load `source` as layer `name` on completion, styled with `qml_name`."""
    details = QgsProcessingContext.LayerDetails(name, context.project(), output_name)
    details.setPostProcessor(_post_processor(qml_name))
    context.addLayerToLoadOnCompletion(source, details)


def load_point_cloud(context, ept_json, name, output_name):
    """Ask Processing to load the EPT index `ept_json` (QGIS's "ept" provider) as point cloud layer `name` on
    completion; Processing cannot tell an ept.json from its path, so the layer is made here and handed over. Returns
    whether QGIS could open it."""
    layer = QgsPointCloudLayer(ept_json, name, "ept")
    if layer.isValid():
        context.temporaryLayerStore().addMapLayer(layer)
        details = QgsProcessingContext.LayerDetails(name, context.project(), output_name)
        details.forceName = True  # not the file's base name, "ept"
        context.addLayerToLoadOnCompletion(layer.id(), details)
    return layer.isValid()


def style_on_completion(context, dest_id, qml_name):
    """Style a sink output (`dest_id`) with `qml_name` where Processing loads it on completion."""
    if context.willLoadLayerOnCompletion(dest_id):
        context.layerToLoadOnCompletionDetails(dest_id).setPostProcessor(_post_processor(qml_name))


def resolve_application_font(app):
    """Set the application font to the installed family it resolves to. Qt's offscreen platform names
    "DejaVu LGC Sans", a font no system has, as the application font; QGIS writes that name into a project
    for every label without a font of its own (the plugin's styles name none), and the desktop then opens
    the project with a warning bar about a missing font."""
    from qgis.PyQt.QtGui import QFont, QFontInfo

    app.setFont(QFont(QFontInfo(app.font()).family(), app.font().pointSize()))
