"""Pushbroom QGIS plugin: photogrammetry for linear-array satellite imagery."""

from .version import VERSION as __version__  # noqa: F401, N811  (pip reads it: pyproject.toml)


def classFactory(iface):
    """QGIS entry point; imports lazily so that loading the plugin stays fast."""
    from .plugin.plugin import create_plugin

    return create_plugin(iface)
