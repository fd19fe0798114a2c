"""qgis_process as a user runs it: a private QGIS profile with the plugin (a link to this repository)
enabled, and the environment that finds the venv's packages."""

import os
import pathlib
import subprocess
import sys

import pushbroom

REPO = pathlib.Path(pushbroom.__file__).resolve().parent
QGIS_PROCESS = "/usr/bin/qgis_process.bin"


def qgis_process_env(folder, plugin=REPO):
    """The environment of qgis_process with a new profile in `folder` (pathlib.Path) that has the plugin
    enabled: a link to `plugin` (this repository, or another checkout of it)."""
    plugins = folder / "profiles" / "default" / "python" / "plugins"
    plugins.mkdir(parents=True)
    (plugins / "pushbroom").symlink_to(plugin)
    site = [p for p in sys.path if p.endswith("site-packages") and ".venv" in p]
    env = dict(
        os.environ,
        QT_QPA_PLATFORM="offscreen",
        QGIS_CUSTOM_CONFIG_PATH=str(folder),
        PYTHONPATH=os.pathsep.join(site + [os.environ.get("PYTHONPATH", "")]),
    )
    subprocess.run([QGIS_PROCESS, "plugins", "enable", "pushbroom"], env=env, capture_output=True)
    return env


def openblas() -> str:
    """OpenBLAS's libblas.so.3 as Debian's alternatives choose it (CBLAS included): LD_PRELOAD puts it before the
    GSL CBLAS that qgis_process links (docs/architecture.md, "Same bits")."""
    import glob

    found = sorted(glob.glob("/usr/lib/*-linux-gnu/libblas.so.3")) + sorted(glob.glob("/lib/*-linux-gnu/libblas.so.3"))
    assert found, "no libblas.so.3 (Debian's libopenblas0)"
    return os.path.realpath(found[0])
