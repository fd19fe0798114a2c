"""The plugin loads in QGIS (offscreen), registers the provider and removes it on unload."""

import configparser
import pathlib
import sys

from qgis.core import QgsApplication

import pushbroom
from pushbroom.plugin import plugin as plugin_module

REPO = pathlib.Path(pushbroom.__file__).resolve().parent


def provider_ids():
    return [p.id() for p in QgsApplication.processingRegistry().providers()]


def test_metadata_has_required_fields():
    meta = configparser.ConfigParser()
    meta.read(REPO / "metadata.txt")
    general = meta["general"]
    for key in (
        "name",
        "qgisMinimumVersion",
        "description",
        "about",
        "version",
        "author",
        "email",
        "repository",
        "tags",
        "category",
        "icon",
    ):
        assert general.get(key, "").strip(), key
    assert general["qgisMinimumVersion"] == "3.22"
    assert general["hasProcessingProvider"] == "yes"
    assert (REPO / general["icon"]).is_file()


def test_plugin_registers_and_removes_provider(qgis_iface):
    plugin = pushbroom.classFactory(qgis_iface)
    plugin.initGui()
    try:
        provider = QgsApplication.processingRegistry().providerById("pushbroom")
        assert provider is plugin.provider
        assert provider.name() == "Pushbroom photogrammetry"
        assert not provider.icon().isNull()
        ids = {a.id() for a in provider.algorithms()}
        assert "pushbroom:createblock" in ids
    finally:
        plugin.unload()
    assert "pushbroom" not in provider_ids()


def test_missing_numba_gives_one_clear_message(qgis_iface, monkeypatch):
    monkeypatch.setitem(sys.modules, "numba", None)  # makes `import numba` raise ImportError
    plugin = pushbroom.classFactory(qgis_iface)
    assert isinstance(plugin, plugin_module.MissingDependencyPlugin)
    assert plugin.missing == ["numba"]
    assert "pip install" in plugin.message() and "numba" in plugin.message()
    plugin.initGui()
    assert "pushbroom" not in provider_ids()
    plugin.unload()
