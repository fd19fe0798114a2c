"""Processing conventions of the algorithms: parameter keys are class constants equal to their names,
the short help stays short, and helpUrl leads to the step's page in docs/steps, which documents every
parameter."""

import pathlib

import pytest
from qgis.PyQt.QtCore import QUrl

from pushbroom.plugin.algorithms import algorithm_classes

#: every algorithm's help is on its page in docs/steps
DOCUMENTED = [cls.NAME for cls in algorithm_classes()]


@pytest.mark.parametrize("name", DOCUMENTED)
def test_short_help_and_page(pushbroom_provider, name):
    algorithm = pushbroom_provider.algorithm(name)
    keys = [p.name() for p in algorithm.parameterDefinitions()] + [o.name() for o in algorithm.outputDefinitions()]
    for key in keys:
        assert getattr(type(algorithm), key) == key  # every key is a class constant of its own name
    assert len(algorithm.shortHelpString()) < 600  # a few sentences; the page has the rest
    page = pathlib.Path(QUrl(algorithm.helpUrl()).toLocalFile())
    text = page.read_text(encoding="utf-8")
    assert text.startswith(f"# {algorithm.displayName()} (pushbroom:{name})\n")
    for key in (p.name() for p in algorithm.parameterDefinitions()):
        assert f"`{key}`" in text  # every parameter is documented
