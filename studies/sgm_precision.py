"""Does the semi-global disparity's V fit predict its own precision? Issue 39 asks a calibrated precision for the
semi-global positions too, so that a cell can choose between them and LSM's by predicted precision.

Model (sgm.py): the V fit's sub-pixel offset delta = (S(d - 1) - S(d + 1)) / (2 slope), slope = max(S(d - 1) -
S(d), S(d + 1) - S(d)); a noise sigma_S in the aggregated costs moves delta by about sigma_S / (sqrt(2) slope), so

    sigma_d = K / slope     (epipolar px),

with K one constant of the census window and the penalties, if the cost noise is alike everywhere.

Method. Simulated 3 km SPOT 5 triplets with the supplied orientation equal to the truth (error_scale 0: the error
is the matching's alone), HRG -> HRS1 and HRG -> HRS2, the tile BOX of HRG with the default DenseParams
(pair_tile.match_pair_tile, every pixel). Each node's error is its image-2 position minus the true conjugate
(matching_scene.Scene.truth), along the epipolar line (epipolar px: EpipolarGrid.epipolar2's u). Errors beyond
BLUNDER px are mismatches, counted apart (the semi-global positions' precision is the rest's).
- By slope decile (both pairs, open classes): median slope, RMS error, and RMS error x median slope (constant
  if the model holds).
- K fitted on the calibration scene's open classes (bare fields, crops): K^2 = mean(e^2) / mean(1 / slope^2);
  then per class and scene RMS(e) / RMS(K / slope) and NMAD(e slope / K) (1 is calibrated), next to a constant
  sigma (the open classes' RMS error: what a precision without the slope would say).

Scenes: SceneConfig.small(error_scale=0) (seed 1, the calibration) and seed 2, 4 km west (small fields among
forest), as studies/dense_precision.py."""

import tempfile

import numpy as np

from pushbroom.algorithms.dense.pair_tile import match_pair_tile
from pushbroom.algorithms.dense.params import DenseParams
from pushbroom.algorithms.simulation import SceneConfig, simulate_scene
from pushbroom.algorithms.simulation.terrain import BARE, CITY, CROPS, FOREST, WATER
from tests.helpers.matching_scene import Scene

BOX = (44, 44, 556, 556)
PAIRS = (("HRG", "HRS1"), ("HRG", "HRS2"))
BLUNDER = 2.0  # epipolar px
OPEN = (BARE, CROPS)
CLASS_NAMES = {BARE: "bare", CROPS: "crops", FOREST: "forest", CITY: "city", WATER: "water"}
SCENES = {
    "seed 1 (calibration)": SceneConfig.small(error_scale=0.0),
    "seed 2, 4 km west": SceneConfig.small(error_scale=0.0, seed=2, centre_lon=-84.235),
}


def scene_errors(config):
    """Per matched node of both pairs: along-epipolar error (px), the V fit's slope, the class."""
    paths = simulate_scene(config, tempfile.mkdtemp() + "/scene")
    out = {"e": [], "slope": [], "cls": []}
    for first, second in PAIRS:
        scene = Scene(paths, first, second)
        x1, y1, x2, y2, slope, info = match_pair_tile(
            scene.image1, scene.image2, scene.model1, scene.model2, BOX, scene.height_range, DenseParams()
        )
        tx, ty, cls = scene.truth(x1, y1)
        grid = info["grid"]
        ok = np.isfinite(x2) & np.isfinite(slope) & np.isfinite(tx)
        e = grid.epipolar2(x2[ok], y2[ok])[0] - grid.epipolar2(tx[ok], ty[ok])[0]
        out["e"].append(e)
        out["slope"].append(slope[ok])
        out["cls"].append(cls[ok])
    return {k: np.concatenate(v) for k, v in out.items()}


def nmad(z):
    return 1.4826 * np.median(np.abs(z - np.median(z)))


def fit_k(e, slope):
    return float(np.sqrt(np.mean(e * e) / np.mean(1.0 / (slope * slope))))


def main():
    k_fit, constant = None, None
    for label, config in SCENES.items():
        r = scene_errors(config)
        good = np.abs(r["e"]) <= BLUNDER
        open_ = np.isin(r["cls"], OPEN) & good
        if k_fit is None:
            k_fit = fit_k(r["e"][open_], r["slope"][open_])
            constant = float(np.sqrt(np.mean(r["e"][open_] ** 2)))
        print(f"\n{label}: {r['e'].size} matched nodes, {100 * (~good).mean():.2f} % beyond {BLUNDER} px")
        print(f"K {k_fit:.2f} (fitted on the calibration scene), constant sigma {constant:.3f} px")
        print("\nOpen classes by slope decile:\n\n| slope decile | median slope | RMS error px | RMS x slope |")
        print("|---|---|---|---|")
        edges = np.quantile(r["slope"][open_], np.linspace(0, 1, 11))
        for q in range(10):
            m = open_ & (r["slope"] >= edges[q]) & (r["slope"] <= edges[q + 1])
            s, rms = float(np.median(r["slope"][m])), float(np.sqrt(np.mean(r["e"][m] ** 2)))
            print(f"| {q + 1} | {s:.1f} | {rms:.3f} | {rms * s:.2f} |")
        print(
            "\n| class | nodes | beyond 2 px % | RMS error px | K / slope: RMS(e) / RMS(sigma); NMAD(e / sigma) | "
            "constant: RMS(e) / sigma |\n|---|---|---|---|---|---|"
        )
        for code, name in CLASS_NAMES.items():
            c = r["cls"] == code
            m = c & good
            if m.sum() < 100:
                continue
            e, sigma = r["e"][m], k_fit / r["slope"][m]
            rms = float(np.sqrt(np.mean(e * e)))
            print(
                f"| {name} | {c.sum()} | {100 * (~good[c]).mean():.2f} | {rms:.3f} | "
                f"{rms / np.sqrt(np.mean(sigma * sigma)):.2f}; {nmad(e / sigma):.2f} | {rms / constant:.2f} |"
            )


if __name__ == "__main__":
    main()
