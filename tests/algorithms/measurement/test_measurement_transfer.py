"""Least-squares transfer of a clicked point into the other images (measurement/transfer.py),
against the simulator's true image positions (points.csv: <image>_col, <image>_row), with the
supplied (perturbed, unadjusted) sensor models for the initial values:

- the small scene with bright markers painted at the points (signalised control points): every
  transfer HRG -> HRS1/HRS2 and HRS1 -> HRG (2:1 scale) accepted and within 0.3 px of the truth,
  from the point's height and from the block's height range;
- the small scene without markers (points in uniform fields, some by a field edge or corner): the
  accepted transfers HRG -> HRS1/HRS2 within 0.3 px, the others refused with a reason;
- only windows around the point are read."""

import csv

import numpy as np
import pytest

from pushbroom.algorithms.block import Block
from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching import imagery
from pushbroom.algorithms.measurement.transfer import Click, transfer

NAMES = ("HRG", "HRS1", "HRS2")


def setup(paths):
    """(images {name: raster path}, models {name: supplied model}, points.csv rows)."""
    images = {n: paths["images"][n]["imagery"] for n in NAMES}
    models = {name: model for name, _, _, model in Block.open_images([images[n] for n in NAMES])}
    with open(paths["points"], newline="") as f:
        return images, models, list(csv.DictReader(f))


@pytest.fixture(scope="module")
def marked(marked_scene):
    return setup(marked_scene)


def errors(result, row):
    """{target: (d col, d row, |d|, rho, sigma_px, ok, reason)} against the row's true positions."""
    out = {}
    for target, t in result.items():
        d = (t.col - float(row[f"{target}_col"]), t.row - float(row[f"{target}_row"]))
        out[target] = (*d, float(np.hypot(*d)), t.rho, t.sigma_px, t.ok, t.reason)
    return out


def table_rows(ids, lines):
    """The transfers' errors (errors() of each point) as rows for Figures.table."""
    return [
        {
            "point": point,
            "target": k,
            "error px": v[2],
            "d col": v[0],
            "d row": v[1],
            "rho": v[3],
            "sigma px": v[4],
            "refused": "" if v[5] else v[6],
        }
        for point, line in zip(ids, lines)
        for k, v in line.items()
    ]


@pytest.mark.parametrize("source", ["HRG", "HRS1"])
@pytest.mark.parametrize("height", ["point", "range"])
def test_marked_points_land_on_the_truth(marked, source, height, figures):
    images, models, rows = marked
    assert len(rows) >= 6
    worst, lines = 0.0, []
    for r in rows:
        h = float(r["h"]) if height == "point" else (float(r["h"]) - 500.0, float(r["h"]) + 500.0)
        result = transfer(images, models, Click(source, float(r[f"{source}_col"]), float(r[f"{source}_row"])), height=h)
        assert sorted(result) == sorted(set(NAMES) - {source})
        e = errors(result, r)
        lines.append(e)
        for target, v in e.items():
            assert v[5] and v[6] == "", (r["id"], target, v)
            worst = max(worst, v[2])
    figures.report("largest error", worst, "px")
    figures.table(f"{source} -> others", table_rows([r["id"] for r in rows], lines))
    assert worst < 0.3


def test_unmarked_points(small_scene):
    """Points inside uniform fields: a distinct correlation peak only near field corners or edges;
    where accepted, HRG -> HRS1/HRS2 lands within 0.3 px of the truth."""
    images, models, rows = setup(small_scene)
    accepted = 0
    for r in rows:
        result = transfer(images, models, Click("HRG", float(r["HRG_col"]), float(r["HRG_row"])), height=float(r["h"]))
        for v in errors(result, r).values():
            # accepted: 0.3 px, three times the acceptance's 0.1 px error ellipse
            assert (v[5] and v[6] == "" and v[2] < 0.3) or (not v[5] and v[6])
            accepted += v[5]
    # which transfers pass the peak, rho and ellipse thresholds here is near a tie (P003 -> HRS2 is refused
    # at an ellipse of 0.105 px against 0.1 px): at least one, so that the accuracy check above is not vacuous
    assert accepted >= 1


def test_only_windows_are_read(marked, monkeypatch, figures):
    images, models, rows = marked
    sizes = []
    read = imagery.Image.read

    def recording(self, x0, y0, cols, rows_):
        sizes.append((int(cols), int(rows_)))
        return read(self, x0, y0, cols, rows_)

    monkeypatch.setattr(imagery.Image, "read", recording)
    r = rows[0]
    transfer(images, models, Click("HRG", float(r["HRG_col"]), float(r["HRG_row"])), height=(-200.0, 800.0))
    transfer(images, models, Click("HRS1", float(r["HRS1_col"]), float(r["HRS1_row"])), height=float(r["h"]))
    figures.report("windows read (cols x rows)", [f"{c} x {r}" for c, r in sizes])
    assert sizes and max(c * w for c, w in sizes) < 200 * 200


def test_refusals(marked):
    images, models, rows = marked
    r = rows[0]
    col, row = float(r["HRG_col"]), float(r["HRG_row"])
    with pytest.raises(InputError, match="image XS is not among"):
        transfer(images, models, Click("XS", col, row), height=300.0)
    with pytest.raises(InputError, match="image HRS3 is not among"):
        transfer(images, models, Click("HRG", col, row), targets=["HRS3"], height=300.0)
    with pytest.raises(InputError, match="outside image HRG"):
        transfer(images, models, Click("HRG", 601.0, row), height=300.0)
    with pytest.raises(InputError, match="give the point's height"):
        transfer(images, models, Click("HRG", col, row))
    far = transfer(images, models, Click("HRG", col, row), height=60000.0)
    assert not any(t.ok for t in far.values())
    assert all("outside image" in t.reason for t in far.values()), far
