"""Translation and help of the Processing glue: every text a dialog shows is in the translation source that
`make` builds with pylupdate5 (i18n/pushbroom.ts), and every parameter has its help from the step's page."""

import html
import pathlib
import re
import subprocess

from qgis.core import QgsProcessingParameterEnum, QgsProcessingParameterFileDestination

from pushbroom.plugin.algorithms.match_points import FIRST_STRATEGIES

ROOT = pathlib.Path(__file__).resolve().parents[2]
TS = ROOT / "i18n" / "pushbroom.ts"


def sources(path):
    """{context: set of source texts} of a .ts file."""
    found = {}
    for context in re.findall(r"<context>(.*?)</context>", path.read_text(encoding="utf-8"), re.S):
        name = re.search(r"<name>(.*?)</name>", context).group(1)
        found[name] = {html.unescape(s) for s in re.findall(r"<source>(.*?)</source>", context, re.S)}
    return found


def shown_texts(algorithm):
    """(what, text) of everything the algorithm's dialog shows in English: its name and group, each parameter's
    description, choices and file filter, each output's description."""
    yield "name", algorithm.displayName()
    yield "group", algorithm.group()
    for p in algorithm.parameterDefinitions():
        yield p.name(), p.description()
        if isinstance(p, QgsProcessingParameterEnum):
            options = p.options()[: len(FIRST_STRATEGIES)] if p.name() == "STRATEGY" else p.options()
            for option in options:
                yield f"{p.name()} choice", option
        if isinstance(p, QgsProcessingParameterFileDestination) and p.fileFilter():
            yield f"{p.name()} filter", p.fileFilter()
    for o in algorithm.outputDefinitions():
        yield o.name(), o.description()


def extracted(text, sources):
    """Whether `text` is one of `sources`, or one of the templates among them (`{}` filled in at run time)."""
    if text in sources:
        return True
    return any(
        re.fullmatch(".+?".join(re.escape(part) for part in re.split(r"\{[^}]*\}", s)), text, re.S)
        for s in sources
        if "{" in s
    )


def test_every_text_of_the_dialogs_is_in_the_translation_source(pushbroom_provider):
    ts = sources(TS)
    assert list(ts) == ["Pushbroom"], list(ts)  # one context, the one `translated` reads
    algorithms = pushbroom_provider.algorithms()
    assert len(algorithms) >= 12
    missing = [
        f"{a.name()} {what}: {text!r}"
        for a in algorithms
        for what, text in shown_texts(a)
        if text and not extracted(text, ts["Pushbroom"]) and not re.fullmatch(r"[\d.]+", text)
    ]
    assert missing == [], "\n".join(missing)


def test_the_translation_source_is_what_pylupdate5_extracts_now(tmp_path):
    """i18n/pushbroom.ts is current: pylupdate5 over the glue's sources finds the same texts (`make` rebuilds it)."""
    files = sorted(str(p) for p in [*ROOT.glob("plugin/*.py"), *ROOT.glob("plugin/algorithms/*.py")])
    fresh = tmp_path / "fresh.ts"
    subprocess.run(["pylupdate5", "-noobsolete", *files, "-ts", str(fresh)], check=True, capture_output=True)
    assert sources(fresh) == sources(TS)


def test_every_parameter_has_its_help_from_the_steps_page(pushbroom_provider):
    bare = [
        f"{a.name()} {p.name()}"
        for a in pushbroom_provider.algorithms()
        for p in a.parameterDefinitions()
        if not p.help() or p.help().startswith("Give ")
    ]
    assert bare == [], "\n".join(bare)
    match = pushbroom_provider.algorithm("matchpoints")
    assert (
        match.parameterDefinition("SIGMA_FACTOR")
        .help()
        .startswith("Group 3 consistency test: deviations below k robust sigma are kept.")
    )
