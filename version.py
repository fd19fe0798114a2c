"""The plugin's version: the version line of metadata.txt, its one source (QGIS reads it there, pip through
pushbroom.__version__, Dask workers are compared by it). A module of its own, so that the engine reads it without
importing the plugin's entry point."""

import os
import re


def _version() -> str:
    with open(os.path.join(os.path.dirname(__file__), "metadata.txt"), encoding="utf-8") as f:
        found = re.search(r"^version=(\S+)", f.read(), re.MULTILINE)
    if found is None:
        raise RuntimeError("metadata.txt has no version line")
    return found.group(1)


VERSION = _version()
