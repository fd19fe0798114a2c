"""How honest is LSM's error ellipse on a resolution-adapted pair? The empirical RMS of the matched
positions over the reported precision, on band-limited patches (tests.helpers.texture, noise 4 DN in
both images) at scale 2:1 along rows as HRG -> HRS, with the template raw and low-passed as
resolution.adapt_resolution does to HRG (imagery.Smoothed, 0.79 / 0.855 px: the 3 km triplet's
HRG -> HRS1); image 2 shows the texture through the same low-pass. lsm_point scales sigma0 for equal
white noise in both images, which the low-passed template does not carry."""

import numpy as np

from pushbroom.algorithms.matching import lsm
from pushbroom.algorithms.matching.imagery import Smoothed
from tests.helpers.texture import texture

SCALE = np.diag([1.0, 2.0])
BLUR = (0.79, 0.855)


def ratio(blur, n=300, noise=4.0, size=41, seed=14):
    """(empirical RMS, reported precision, ratio) of n patch matches."""
    rng = np.random.default_rng(seed)
    jj, ii = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    c = size / 2.0
    errors, reported = [], []
    for _ in range(n):
        tex = texture(rng)
        img1 = (100 + 30 * tex(jj, ii) + rng.normal(0, noise, jj.shape)).astype(np.float32)
        if blur is not None:
            img1 = Smoothed(img1, *blur).read(0, 0, size, size)[0]
        truth = c + rng.uniform(-0.5, 0.5, 2)
        t = np.array([c, c]) - SCALE @ truth
        img2 = (100 + 30 * tex(jj + t[0], 2 * ii + t[1], blur or (0.0, 0.0)) + rng.normal(0, noise, jj.shape)).astype(
            np.float32
        )
        init = truth + rng.uniform(-1, 1, 2)
        rec, status = lsm.match_points(img1, img2, [c], [c], [init[0]], [init[1]], affine=(1.0, 0.0, 0.0, 0.5))
        if status[0] == lsm.OK:
            errors.append([rec["x2"][0] - truth[0], rec["y2"][0] - truth[1]])
            reported.append(float(rec["semi_major"][0]) ** 2 + float(rec["semi_minor"][0]) ** 2)
    rms = float(np.sqrt(np.mean(np.sum(np.square(errors), 1))))
    predicted = float(np.sqrt(np.mean(reported)))
    return rms, predicted, rms / predicted


if __name__ == "__main__":
    for label, blur in (("raw template", None), (f"template low-passed {BLUR[0]} / {BLUR[1]} px", BLUR)):
        rms, predicted, r = ratio(blur)
        print(f"scale 2:1, {label}: empirical RMS {rms:.4f} px, reported {predicted:.4f} px, ratio {r:.2f}")
