"""Least-squares matching throughput: points/s with a 19 x 19 template on demo-like texture
(Gaussian-filtered white noise, sigma 1.5 px, plus noise), image 2 shifted by a sub-pixel amount
and rotated 5 deg; initial values 0.7 px off. 1 thread vs 2 threads (numba.set_num_threads);
times are the best of three after JIT warm-up."""

import os

import numba
import numpy as np
from scipy import ndimage

from pushbroom.algorithms.matching import lsm
from pushbroom.algorithms.matching.params import LsmParams
from tests.benchmarks.benchutil import best_time, thread_counts


def images(size=1200, seed=0):
    rng = np.random.default_rng(seed)
    base = ndimage.gaussian_filter(rng.normal(size=(size, size)), 1.5)
    base = 100 + 30 * base / base.std()
    th = np.radians(5.0)
    c, s = np.cos(th), np.sin(th)
    matrix = np.array([[c, -s], [s, c]])
    centre = np.array([size / 2, size / 2])
    offset = centre - matrix @ centre + np.array([0.37, -0.21])
    img2 = ndimage.affine_transform(base, matrix, offset=offset, order=3)
    img1 = base + rng.normal(0, 2, base.shape)
    img2 = img2 + rng.normal(0, 2, base.shape)
    return img1.astype(np.float32), img2.astype(np.float32), matrix, offset


def run(npoints=20000):
    img1, img2, matrix, offset = images()
    rng = np.random.default_rng(1)
    xy1 = rng.uniform(100, 1100, (npoints, 2))
    # array (row, col) of image 1 <- matrix @ (row, col) + offset of image 2; invert for truth
    rc2 = np.linalg.solve(matrix, (xy1[:, ::-1] - 0.5 - offset).T).T
    xy2 = rc2[:, ::-1] + 0.5
    init = xy2 + rng.uniform(-0.5, 0.5, xy2.shape)
    inv = np.linalg.inv(matrix)  # in (row, col); affine in (x, y) order below
    affine = (1.0, 0.0, 0.0, 1.0)
    params = LsmParams()
    rows = []
    for threads in thread_counts():

        def call():
            return lsm.match_points(img1, img2, xy1[:, 0], xy1[:, 1], init[:, 0], init[:, 1], affine, params)

        seconds = best_time(call)
        rec, status = call()
        ok = lsm.accepted(rec, status, params)
        err = np.hypot(rec["x2"][ok] - xy2[ok, 0], rec["y2"][ok] - xy2[ok, 1])
        rows.append(
            {
                "operation": "lsm match_points",
                "template": params.template,
                "threads": threads,
                "points": npoints,
                "seconds": seconds,
                "points/s": npoints / seconds,
                "points/s/core": npoints / seconds / threads,
                "accepted": float(ok.mean()),
                "mean iterations": float(rec["iterations"][ok].mean()),
                "rms px": float(np.sqrt((err**2).mean())),
                "a2 true": float(inv[1, 0]),
                "threading layer": numba.threading_layer(),
                "cores": os.cpu_count(),
            }
        )
    return rows


if __name__ == "__main__":
    results = run()
    print(
        f"{'operation':<18} {'threads':>7} {'points':>7} {'seconds':>8} {'points/s':>10} {'per core':>10} "
        f"{'accepted':>8} {'iter':>5} {'rms px':>7}"
    )
    for r in results:
        print(
            f"{r['operation']:<18} {r['threads']:>7} {r['points']:>7} {r['seconds']:>8.4f} {r['points/s']:>10.0f} "
            f"{r['points/s/core']:>10.0f} {r['accepted']:>8.3f} {r['mean iterations']:>5.2f} {r['rms px']:>7.4f}"
        )
    print(f"(threading layer {results[0]['threading layer']}, {results[0]['cores']} cores)")
