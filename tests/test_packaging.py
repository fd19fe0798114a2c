"""Packaging: pyproject.toml lists every package, its extras equal the Makefile's pins, the version has
one source (metadata.txt), and the wheel installs and imports."""

import pathlib
import re
import subprocess
import sys

import pytest
import tomllib
from packaging.requirements import Requirement

import pushbroom

ROOT = pathlib.Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
NOT_PACKAGED = {"tests", "scripts", "build", "dist", "docs", "resources", "studies"}


def makefile_pins():
    """{name: Requirement} of the Makefile's PIP_PINS."""
    text = (ROOT / "Makefile").read_text(encoding="utf-8")
    value = re.search(r"^PIP_PINS := ((?:.*\\\n)*.*)$", text, re.MULTILINE).group(1).replace("\\\n", " ")
    return {r.name: r for r in map(Requirement, value.split())}


def test_every_package_is_listed():
    folders = {
        ".".join(("pushbroom",) + p.parent.relative_to(ROOT).parts)
        for p in ROOT.rglob("__init__.py")
        if not ({p.relative_to(ROOT).parts[0]} & NOT_PACKAGED) and ".venv" not in p.parts
    }
    assert set(PYPROJECT["tool"]["setuptools"]["packages"]) == {f.rstrip(".") for f in folders}


def test_extras_equal_the_makefile_pins():
    pins = makefile_pins()
    for extra in ("test", "lint"):
        for requirement in map(Requirement, PYPROJECT["project"]["optional-dependencies"][extra]):
            assert str(pins[requirement.name]) == str(requirement), extra


def test_makefile_pins_satisfy_the_declared_ranges():
    declared = [Requirement(r) for r in PYPROJECT["project"]["dependencies"]]
    declared += [Requirement(r) for extra in PYPROJECT["project"]["optional-dependencies"].values() for r in extra]
    by_name = {r.name: r for r in declared}
    for name, pin in makefile_pins().items():
        if name in by_name:  # llvmlite comes with numba
            assert by_name[name].specifier.contains(next(iter(pin.specifier)).version), name


def test_the_version_has_one_source():
    metadata = re.search(r"^version=(\S+)", (ROOT / "metadata.txt").read_text(encoding="utf-8"), re.MULTILINE)
    assert "version" not in PYPROJECT["project"] and "version" in PYPROJECT["project"]["dynamic"]
    assert pushbroom.__version__ == metadata.group(1)


@pytest.mark.slow
def test_the_wheel_installs_and_imports(tmp_path):
    def run(*args):
        proc = subprocess.run(args, capture_output=True, text=True, cwd=tmp_path)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        return proc.stdout

    run(sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "--no-build-isolation", "-q", "-w", "wheels")
    run("/usr/bin/python3", "-m", "venv", "--system-site-packages", "venv")
    run("venv/bin/python", "-m", "pip", "install", "-q", "--no-deps", *map(str, (tmp_path / "wheels").glob("*.whl")))
    out = run(
        "venv/bin/python",
        "-c",
        "import os, sys, pushbroom, pushbroom.algorithms.matching, pushbroom.plugin.algorithms\n"
        "from pushbroom.resource_files import resource_path\n"
        "sys.stdout.write(' '.join(map(str, (pushbroom.__file__, pushbroom.__version__, "
        "os.path.isfile(resource_path('styles', 'dem.qml'))))))",
    )
    location, version, styles = out.split()
    assert location.startswith(str(tmp_path / "venv")) and version == pushbroom.__version__ and styles == "True"
