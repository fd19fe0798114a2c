"""Pushbroom QGIS plugin: photogrammetry for linear-array satellite imagery."""
import os
import re


def _version():
    """The version line of metadata.txt, its one source (QGIS reads it there, pip through __version__)."""
    with open(os.path.join(os.path.dirname(__file__), "metadata.txt"), encoding="utf-8") as f:
        return re.search(r"^version=(\S+)", f.read(), re.MULTILINE).group(1)


__version__ = _version()


def classFactory(iface):
    """QGIS entry point; imports lazily so that loading the plugin stays fast."""
    from .plugin.plugin import create_plugin
    return create_plugin(iface)
