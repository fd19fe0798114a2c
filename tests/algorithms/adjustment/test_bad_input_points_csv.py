"""Property test of importpoints' CSV parser (control_points.read_csv): every mutation of a valid point file
(lines dropped, doubled or cut, cells emptied or replaced by text, NaN, huge numbers or garbage, delimiters
changed, bytes that are not UTF-8) gives the engine's error naming the file, or valid observations; never
another exception."""
import math

import numpy as np
from hypothesis import HealthCheck, given, settings, strategies as st

from pushbroom.algorithms.adjustment import control_points as cp
from pushbroom.algorithms.errors import PushbroomError

IMAGES = {"HRG": 1, "HRS1": 2}
VALID = ("id,role,lon,lat,h,sigma_e,HRG_col,HRG_row,HRS1_col,HRS1_row,HRS1_sigma\n"
         "P1,control,-84.20,36.60,300.5,2.0,100.5,200.25,50.0,60.0,0.3\n"
         "P2,check,-84.21,36.61,310.0,,110.0,210.0,,,\n"
         "P3,,-84.22,36.62,320.0,1.5,120.0,220.0,70.5,80.5,\n")
CELLS = st.sampled_from(["", "nan", "inf", "-inf", "1e308", "-1e400", "abc", "0", "-0.0", "1,5", '"x"', "\x00",
                         " 12 ", "control", "check", "tie", "P1", "é", "999999999999999999999"])


@st.composite
def mutated(draw):
    lines = VALID.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["drop", "double", "cut", "cell", "delimiter", "swap"]))
        if action == "drop" and len(lines) > 1:
            lines.pop(k)
        elif action == "double":
            lines.insert(k, lines[k])
        elif action == "cut":
            lines[k] = lines[k][:draw(st.integers(0, max(len(lines[k]) - 1, 0)))]
        elif action == "cell":
            cells = lines[k].split(",")
            cells[draw(st.integers(0, len(cells) - 1))] = draw(CELLS)
            lines[k] = ",".join(cells)
        elif action == "delimiter":
            lines[k] = lines[k].replace(",", draw(st.sampled_from([";", "\t", " ", ",,"])))
        elif action == "swap" and len(lines) > 1:
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
    data = "\n".join(lines).encode("utf-8")
    if draw(st.booleans()):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(min_size=1, max_size=8)) + data[at:]
    return data


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=mutated(), crs=st.sampled_from([None, "EPSG:32616"]))
def test_mutated_point_files_give_observations_or_the_engines_error(tmp_path, data, crs):
    path = tmp_path / "points.csv"
    path.write_bytes(data)
    try:
        obs = cp.read_csv(path, IMAGES, crs=crs)
    except PushbroomError as exc:
        assert str(path) in str(exc) or "point" in str(exc)         # the message says which file or point
        return
    p, m = obs.points, obs.measurements
    # what comes back is usable: named, finite WGS 84 positions, positive sigmas, measurements of known images
    assert len(p) and all(name for name in p["name"])
    assert np.isfinite(p["lon"]).all() and np.isfinite(p["lat"]).all() and np.isfinite(p["h"]).all()
    assert (np.abs(p["lat"]) <= 90).all()
    assert all(math.isfinite(s) and s > 0 for key in ("sigma_e", "sigma_n", "sigma_h") for s in p[key])
    assert set(m["image_id"].tolist()) <= set(IMAGES.values())
    assert np.isfinite(m["col"]).all() and np.isfinite(m["row"]).all() and (m["sigma"] > 0).all()
