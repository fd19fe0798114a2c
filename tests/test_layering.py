"""The layers of the package, checked on the imports of every module.

- The engine (`algorithms/`) imports neither QGIS, Qt, `plugin/` nor `ui/`.
- The widgets (`ui/`) do not import the Processing glue (`plugin/`).
- The engine packages import each other without cycles. A node is a subpackage of `algorithms/`
  (`algorithms.matching`) or a top-level engine module (`algorithms.atomic`); imports inside a node
  do not count.
- No module of the package imports itself back through others: no cycle between modules, inside a
  subpackage too.

Imports are read with `ast`, those inside functions included, relative imports resolved. Imports under
`if TYPE_CHECKING:` are for the type checker only, never run, and do not count.
"""

import ast
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = "pushbroom"
NOT_PACKAGED = {"tests", "scripts", "build", "dist", "docs", "resources", "studies"}
QT_OR_QGIS = ("qgis", "PyQt5", "PyQt6", "PySide2", "PySide6", "qtpy", "sip")


def package_modules(root, package):
    """{dotted module name: file} of every module of the package rooted at `root`."""
    modules = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[0] in NOT_PACKAGED or any(p.startswith(".") for p in parts):
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join((package,) + parts)] = path
    return modules


def imports_of(module, path, modules):
    """(line, imported module) of every import in `path`, relative imports resolved.

    `from a import b` counts as an import of `a.b` when that is a module of the package, else of `a`.
    """
    is_package = path.name == "__init__.py"
    found = []
    for node in _runtime_nodes(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".")
                base = base[: len(base) - node.level + (1 if is_package else 0)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.append((node.lineno, sub if sub in modules else target))
    return sorted(found)


def _type_checking(node):
    """Whether `node` is an `if TYPE_CHECKING:` (or `typing.TYPE_CHECKING`) block."""
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _runtime_nodes(tree):
    """The nodes of `tree` outside `if TYPE_CHECKING:` bodies (their `else` branches run)."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if _type_checking(node):
            stack.extend(node.orelse)
        else:
            stack.extend(ast.iter_child_nodes(node))


def engine_node(module, package):
    """The cycle-check node of an engine module: `algorithms.<subpackage or module>`, else None."""
    parts = module.split(".")
    if parts[0] != package or len(parts) < 3 or parts[1] != "algorithms":
        return None
    return ".".join(parts[1:3])


def find_cycle(graph):
    """One cycle of the directed `graph` ({node: set of nodes}) as a closed path [a, b, ..., a], or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def layering_violations(root, package=PACKAGE):
    """Messages for every broken layering rule in the package rooted at `root`."""
    modules = package_modules(root, package)
    problems, graph, module_graph = [], {}, {}
    for module, path in modules.items():
        layer = module.split(".")[1] if "." in module else None
        where = path.relative_to(root)
        for line, imported in imports_of(module, path, modules):
            top, parts = imported.split(".")[0], imported.split(".")
            inner = parts[1] if top == package and len(parts) > 1 else None
            if layer == "algorithms" and (top in QT_OR_QGIS or inner in ("plugin", "ui")):
                problems.append(f"{where}:{line}: the engine imports {imported}")
            if layer == "ui" and inner == "plugin":
                problems.append(f"{where}:{line}: ui imports the Processing glue {imported}")
            source, target = engine_node(module, package), engine_node(imported, package)
            if source and target and source != target:
                graph.setdefault(source, set()).add(target)
            if imported in modules and imported != module:
                module_graph.setdefault(module, set()).add(imported)
    if cycle := find_cycle(graph):
        problems.append("import cycle between engine packages: " + " -> ".join(cycle))
    if cycle := find_cycle(module_graph):
        problems.append("import cycle between modules: " + " -> ".join(cycle))
    return problems


def write_package(root, files):
    """A synthetic package: {relative path: source}; every folder gets an __init__.py."""
    for name, source in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
    for folder in [root, *(p for p in root.rglob("*") if p.is_dir())]:
        (folder / "__init__.py").touch()


SOUND = {
    "algorithms/matching/lsm.py": "from ..interpolation import bilinear\n",
    "algorithms/ortho/resampling.py": "from pushbroom.algorithms.interpolation import cubic\n",
    "algorithms/interpolation.py": "import numpy\n",
    "ui/view.py": "from ..resource_files import resource_path\nfrom qgis.core import QgsPoint\n",
    "plugin/plugin.py": "from ..ui import view\nfrom ..algorithms.matching import lsm\n",
    "resource_files.py": "",
}


def test_checker_passes_a_sound_package(tmp_path):
    write_package(tmp_path, SOUND)
    assert layering_violations(tmp_path) == []


def test_checker_reports_a_cycle_with_its_path(tmp_path):
    # a function-level import closes matching -> interpolation -> ortho -> matching
    write_package(
        tmp_path, {**SOUND, "algorithms/interpolation.py": "def kernel():\n    from .ortho import resampling\n"}
    )
    assert layering_violations(tmp_path) == [
        "import cycle between engine packages: "
        "algorithms.interpolation -> algorithms.ortho -> algorithms.interpolation",
        "import cycle between modules: pushbroom.algorithms.interpolation -> pushbroom.algorithms.ortho.resampling -> "
        "pushbroom.algorithms.interpolation",
    ]


def test_checker_reports_a_cycle_inside_a_package_through_a_function_level_import(tmp_path):
    # matching.lsm imports matching.ncc, whose function imports lsm back
    write_package(
        tmp_path,
        {
            **SOUND,
            "algorithms/matching/lsm.py": "from .ncc import score\n",
            "algorithms/matching/ncc.py": "def score():\n    from .lsm import bilinear\n",
        },
    )
    assert layering_violations(tmp_path) == [
        "import cycle between modules: pushbroom.algorithms.matching.lsm -> pushbroom.algorithms.matching.ncc -> "
        "pushbroom.algorithms.matching.lsm"
    ]


def test_checker_ignores_imports_for_the_type_checker_only(tmp_path):
    source = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .lsm import bilinear\n"
    write_package(
        tmp_path,
        {**SOUND, "algorithms/matching/ncc.py": source, "algorithms/matching/lsm.py": "from .ncc import score\n"},
    )
    assert layering_violations(tmp_path) == []


def test_checker_reports_ui_importing_plugin(tmp_path):
    write_package(tmp_path, {**SOUND, "ui/view.py": "from ..plugin.plugin import resource_path\n"})
    assert layering_violations(tmp_path) == [
        "ui/view.py:1: ui imports the Processing glue pushbroom.plugin.plugin",
        "import cycle between modules: pushbroom.plugin.plugin -> pushbroom.ui.view -> pushbroom.plugin.plugin",
    ]


def test_checker_reports_the_engine_importing_qt_or_glue(tmp_path):
    write_package(
        tmp_path,
        {
            **SOUND,
            "algorithms/ortho/resampling.py": (
                "import PyQt5.QtCore\nfrom ... import plugin\nfrom pushbroom.ui import view\n"
            ),
        },
    )
    assert layering_violations(tmp_path) == [
        "algorithms/ortho/resampling.py:1: the engine imports PyQt5.QtCore",
        "algorithms/ortho/resampling.py:2: the engine imports pushbroom.plugin",
        "algorithms/ortho/resampling.py:3: the engine imports pushbroom.ui.view",
    ]


def test_the_package_keeps_its_layers():
    assert len(package_modules(ROOT, PACKAGE)) > 50
    assert layering_violations(ROOT) == []


def test_importing_every_engine_module_loads_no_qgis():
    modules = [m for m in package_modules(ROOT, PACKAGE) if m.startswith(f"{PACKAGE}.algorithms")]
    code = (
        "import importlib, sys\n"
        f"for m in {modules!r}: importlib.import_module(m)\n"
        f"bad = sorted(m for m in sys.modules if m.split('.')[0] in {QT_OR_QGIS!r})\n"
        "sys.stdout.write(str(bad)); sys.exit(1 if bad else 0)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
