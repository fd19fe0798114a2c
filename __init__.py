"""Pushbroom QGIS plugin: photogrammetry for linear-array satellite imagery."""


def classFactory(iface):  # noqa: N802 (QGIS plugin entry point)
    """QGIS entry point; imports lazily so that loading the plugin stays fast."""
    from .plugin.plugin import create_plugin
    return create_plugin(iface)
