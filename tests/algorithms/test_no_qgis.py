"""The engine under algorithms/ must not import QGIS or Qt (DESIGN.md, Layout)."""
import ast
import pathlib
import subprocess
import sys

ALGORITHMS = pathlib.Path(__file__).resolve().parents[2] / "algorithms"
FORBIDDEN = ("qgis", "PyQt5", "PyQt6", "PySide2", "PySide6", "qtpy", "sip")


def forbidden_imports(source):
    """(line, module) of every import of a forbidden top-level package in `source`."""
    hits = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        hits += [(node.lineno, n) for n in names if n.split(".")[0] in FORBIDDEN]
    return hits


def test_checker_catches_qgis_imports():
    assert forbidden_imports("import numpy\nfrom qgis.core import QgsPoint\nimport PyQt5.QtCore as q\n") == [
        (2, "qgis.core"), (3, "PyQt5.QtCore")]


def test_no_module_under_algorithms_imports_qgis_or_qt():
    files = sorted(ALGORITHMS.rglob("*.py"))
    assert len(files) > 5
    offenders = {str(f.relative_to(ALGORITHMS)): hits for f in files
                 if (hits := forbidden_imports(f.read_text(encoding="utf-8")))}
    assert offenders == {}


def test_importing_every_engine_module_loads_no_qgis():
    modules = [".".join(("pushbroom", "algorithms") + f.relative_to(ALGORITHMS).with_suffix("").parts)
               for f in sorted(ALGORITHMS.rglob("*.py"))]
    modules = [m[: -len(".__init__")] if m.endswith(".__init__") else m for m in modules]
    code = ("import importlib, sys\n"
            f"for m in {modules!r}: importlib.import_module(m)\n"
            f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r})\n"
            "sys.exit(f'imported {bad}' if bad else 0)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
