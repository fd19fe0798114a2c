"""The figures a run of the tests measured: an RMS against the truth, a ratio to the predicted precision, a
count. Tests report them through the `figures` fixture (tests/conftest.py) beside the asserts that bound them,
and so do the module and session fixtures that measure what several tests share; the session collects them by
the test that was running, writes them to build/test-figures.md and shows them in pytest's terminal summary."""

import numbers

import numpy as np


def format_value(value):
    """A figure as text: reals with 4 significant digits, sequences and mappings element by element."""
    if isinstance(value, str):
        return str(value)  # a numpy str_ as a str
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return f"{float(value):.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {format_value(v)}" for k, v in value.items())
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (set, frozenset)):
        value = sorted(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


class Figures:
    """Every test's figures of a session, in the order they were reported; `current` is the node id of the
    test that is running (set by the conftest before its fixtures)."""

    def __init__(self):
        self._tests = {}
        self.current = "(no test)"

    def report(self, name, value, unit="", note=""):
        """One figure: `name` = `value` `unit`, with an optional note (the reference, the bound)."""
        entry = ("figure", str(name), format_value(value), str(unit), str(note))
        self._tests.setdefault(self.current, []).append(entry)

    def table(self, name, rows):
        """A table of figures: `rows` are dicts with the same keys (the columns)."""
        rows = list(rows)
        columns = list(rows[0]) if rows else []
        cells = [[format_value(r.get(c, "")) for c in columns] for r in rows]
        self._tests.setdefault(self.current, []).append(("table", str(name), [str(c) for c in columns], cells))

    def entries(self):
        """{test: [entry, ...]}, in str, lists and tuples only (what a pytest-xdist worker sends)."""
        return {test: list(entries) for test, entries in self._tests.items()}

    def merge(self, entries):
        """Add the `entries` of another session (a pytest-xdist worker's)."""
        for test, found in entries.items():
            self._tests.setdefault(test, []).extend(tuple(e) for e in found)

    def __bool__(self):
        return any(self._tests.values())

    def _reported(self):
        return [(test, entries) for test, entries in self._tests.items() if entries]

    def lines(self):
        """Plain text for the terminal: a test's node id, then its figures and tables indented."""
        out = []
        for test, entries in self._reported():
            out.append(test)
            for entry in entries:
                if entry[0] == "figure":
                    _, name, value, unit, note = entry
                    out.append(f"    {name}: {value}{' ' + unit if unit else ''}{f'  ({note})' if note else ''}")
                else:
                    _, name, columns, rows = entry
                    widths = [max(len(str(c)), *(len(r[k]) for r in rows)) for k, c in enumerate(columns)]
                    out.append(f"    {name}:")
                    out += [
                        "      " + "  ".join(str(v).rjust(w) for v, w in zip(row, widths)) for row in [columns] + rows
                    ]
        return out

    def markdown(self):
        """The figures as a markdown document: a section per test, a table of its figures, then its tables."""
        cell = lambda v: str(v).replace("|", "\\|")
        out = ["# Figures measured by the tests", ""]
        for test, entries in self._reported():
            out += [f"## {cell(test)}", ""]
            single = [e for e in entries if e[0] == "figure"]
            if single:
                out += ["| figure | value | unit | note |", "|---|---|---|---|"]
                out += [f"| {' | '.join(cell(v) for v in e[1:])} |" for e in single]
                out.append("")
            for _, name, columns, rows in (e for e in entries if e[0] == "table"):
                out += [
                    f"{cell(name)}:",
                    "",
                    "| " + " | ".join(cell(c) for c in columns) + " |",
                    "|" + "---|" * len(columns),
                ]
                out += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
                out.append("")
        return "\n".join(out)


def section_rows(section):
    """The rows of a report Section (adjustment.report: header, rows) as rows for Figures.table."""
    return [dict(zip(section.header, row)) for row in section.rows]
