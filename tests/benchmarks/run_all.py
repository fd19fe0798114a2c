"""Run every tests/benchmarks/bench_*.py (each has `run() -> list of dict rows`) and write one
markdown file with a table per benchmark. Usage, from the repository root (the benchmarks import the
test helpers as the `tests` package): python -m tests.benchmarks.run_all OUTPUT.md [name ...]; one
benchmark alone: python -m tests.benchmarks.bench_<name>."""

import importlib
import os
import pathlib
import platform
import sys
import time

from pushbroom.algorithms.atomic import write_text

HERE = pathlib.Path(__file__).resolve().parent


def markdown_table(rows):
    """Rows (dicts with the same keys) as a markdown table; floats with 4 significant digits."""
    keys = list(rows[0])
    fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def main(output, names):
    sections = [
        f"# Pushbroom benchmarks\n\n{platform.node()}: {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M')}\n"
    ]
    for path in sorted(HERE.glob("bench_*.py")):
        if names and path.stem not in names:
            continue
        module = importlib.import_module(f"tests.benchmarks.{path.stem}")
        print(f"running {path.stem} ...", flush=True)
        rows = module.run()
        title = (module.__doc__ or path.stem).strip().splitlines()[0]
        sections.append(f"## {path.stem}: {title}\n\n{markdown_table(rows)}\n")
        write_text(output, "\n".join(sections))  # what ran so far survives a later failure
    print("\n".join(sections))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
