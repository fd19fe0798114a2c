"""The tests' figures cross from a pytest-xdist worker to the controller (`make test` runs two workers): a
worker's entries pass execnet's serializer, which takes no numpy scalar, and merged they read as the worker's."""

import execnet
import numpy as np

from tests.helpers.figures import Figures


def test_figures_pass_execnet_and_merge_to_the_same_lines():
    worker = Figures()
    worker.current = "tests/a.py::test_one"
    worker.report("RMS", np.float64(1.23456), "m", "bound 2 m")
    worker.table("per class", [{"class": np.str_("forest"), "n": np.int64(3), "RMS": np.float32(4.5)}])
    worker.current = "tests/b.py::test_two"
    worker.report("cells", [np.int32(1), 2.0])
    sent = execnet.loads(execnet.dumps(worker.entries()))
    controller = Figures()
    controller.merge(sent)
    assert controller.lines() == worker.lines() and controller.markdown() == worker.markdown()
