"""docs/architecture.md's step table is the provider's list of algorithms: every Processing algorithm has
one row (id, plugin file, engine entry point, test) and every row names things that exist; each
algorithm's `execute` is thin (reads its parameters, calls its entry point, loads the outputs)."""

import ast
import importlib
import pathlib
import re

from pushbroom.plugin.algorithms import algorithm_classes

REPO = pathlib.Path(__file__).resolve().parents[2]
#: longest `execute` of a Processing algorithm (issue 20: "under about 25 lines")
MAX_EXECUTE_LINES = 25


def step_rows():
    """{processing id: (plugin file, entry point, test)} of the table under '## Steps'."""
    text = (REPO / "docs" / "architecture.md").read_text()
    section = text.split("\n## Steps", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip().strip("`") for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[0].startswith("pushbroom:"):
            rows[cells[0]] = tuple(cells[1:])
    return rows


def test_the_table_lists_exactly_the_providers_algorithms():
    assert sorted(step_rows()) == sorted(f"pushbroom:{cls.NAME}" for cls in algorithm_classes())


def test_every_row_names_a_plugin_file_an_entry_point_and_a_test_that_exist():
    classes = {f"pushbroom:{cls.NAME}": cls for cls in algorithm_classes()}
    for step, (plugin_file, entry, test) in step_rows().items():
        source = (REPO / plugin_file).read_text()
        assert f'NAME = "{classes[step].NAME}"' in source, (step, plugin_file)  # the row's file defines the step
        module, _, function = entry.rpartition(".")
        target = getattr(importlib.import_module(f"pushbroom.{module}"), function)
        assert callable(target), entry
        assert re.search(rf"\b{function}\b", source), (step, entry)  # the algorithm calls its entry point
        for path in test.split(", "):
            assert (REPO / path.split("::")[0]).is_file(), (step, path)


def test_every_execute_is_thin():
    for path in sorted((REPO / "plugin" / "algorithms").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and node.name in ("execute", "processAlgorithm"):
                lines = node.end_lineno - node.lineno + 1
                assert lines <= MAX_EXECUTE_LINES, f"{path.name}: {node.name} has {lines} lines"
