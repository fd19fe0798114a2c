"""No function of the package takes more than 8 arguments, and no numba kernel more than 12 (issue 38): settings
travel as value objects (docs/architecture.md, "Types and format"). `self` and `cls` do not count; *args and
**kwargs count one each. Read with `ast`, like the layering test."""

import ast

from tests.test_layering import NOT_PACKAGED, ROOT

#: the most arguments of a function, and of a numba kernel
MOST, MOST_KERNEL = 8, 12
KERNEL_DECORATORS = {"njit", "jit", "vectorize", "guvectorize"}


def _decorator_name(node):
    node = node.func if isinstance(node, ast.Call) else node
    return node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")


def long_signatures(root):
    """'path:line name(n)' of every function of the package at `root` over its limit."""
    found = []
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root).parts
        if parts[0] in NOT_PACKAGED or any(p.startswith(".") for p in parts):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            a = node.args
            names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs]
            count = len(names) - (names[:1] in (["self"], ["cls"])) + bool(a.vararg) + bool(a.kwarg)
            kernel = any(_decorator_name(d) in KERNEL_DECORATORS for d in node.decorator_list)
            if count > (MOST_KERNEL if kernel else MOST):
                found.append(f"{path.relative_to(root)}:{node.lineno} {node.name}({count})")
    return found


def test_the_checker_counts_arguments(tmp_path):
    (tmp_path / "m.py").write_text(
        "from numba import njit\n"
        "def ok(a, b, c, d, e, f, g, h): pass\n"
        "def long(a, b, c, d, e, f, g, *args, **kwargs): pass\n"
        "class C:\n    def method(self, a, b, c, d, e, f, g, h): pass\n"
        "@njit(cache=True)\ndef kernel(a, b, c, d, e, f, g, h, i, j, k, l): pass\n"
        "@njit\ndef big(a, b, c, d, e, f, g, h, i, j, k, l, m): pass\n"
    )
    assert long_signatures(tmp_path) == ["m.py:3 long(9)", "m.py:9 big(13)"]


def test_no_function_takes_a_long_list_of_arguments():
    assert len(list(ROOT.glob("algorithms/**/*.py"))) > 100
    assert long_signatures(ROOT) == []
