"""Shared fixture data for the region-growing and seed tests: a small simulated SPOT 5 triplet and
the true image-2 position of image-1 points (image-1 truth ray meets the true DSM, projected by the
image-2 truth model).

Two truths: `truth` is pointwise (the ray of the template centre), the one the issue's targets
use; `area_truth` is what an area matcher can deliver where the surface is not one plane within
the template: the gradient-weighted least-squares affine fit (LSM's own normal equations) of the
pointwise truth of every template pixel, at the centre. On the simulated triplet the two differ
by 0.4-0.6 px RMS on forest crowns and buildings (height discontinuities inside the template) and
by 0.136 px RMS on fields (sub-template relief; 0.099 px with fractal = 0: the cubic-interpolated
DEM's own curvature over 95 m is the larger part, plane-fit residual 0.71 m vs 0.46 m fractal).
The matcher's own error vs the area truth (0.154 px, deterministic: same with noise 0) is larger
than the relief gap; centre-weighted LSM does not reduce the point-truth RMS (prototype: Gaussian
sigma 9.5 / 6 / 4.75 / 3.5 px -> 0.206 / 0.207 / 0.212 / 0.237 px vs 0.208 unweighted).
`area_truth` can weight the samples as MPGC's support weights do (mpgc.py; support_reference, a
numpy implementation of mpgc_kernels.support_weights), computed on the
template without the resolution adaptation's low-pass (the 5 x 5 box means hardly differ)."""

import numpy as np
from osgeo import gdal
from scipy import ndimage

from pushbroom.algorithms import sensors
from pushbroom.algorithms.dem_store import read_dem
from pushbroom.algorithms.matching.imagery import Image, Smoothed
from pushbroom.algorithms.matching.mpgc_kernels import SUPPORT_BOX
from pushbroom.algorithms.matching.pair_geometry import local_affine
from pushbroom.algorithms.matching.params import GrowParams
from pushbroom.algorithms.matching.region_growing import Lattice
from pushbroom.algorithms.matching.resolution import adapt_resolution
from pushbroom.algorithms.simulation.terrain import BARE, CITY, CROPS, FOREST

SINGLE_SURFACE = (BARE, CROPS)  # DSM = DTM: one (rough) surface inside a template
DISCONTINUOUS = (FOREST, CITY)  # crowns on an 8 m lattice, buildings: height steps inside a template
LOW_CONTRAST_DN = 5.0  # ground DN std over the template footprint below which a node is low texture


def support_reference(f, half, centre, similarity):
    """Support weights (mpgc_kernels.support_weights) in numpy: Gaussian of the distance from the
    centre times a Gaussian of the difference of the SUPPORT_BOX box means (zero-padded sums over
    the template / the samples they hold) from the centre's, in units of similarity x std(f)."""
    side = 2 * half + 1
    img = f.reshape(side, side)
    box = np.ones((SUPPORT_BOX, SUPPORT_BOX))
    mean = ndimage.convolve(img, box, mode="constant") / ndimage.convolve(np.ones_like(img), box, mode="constant")
    k, l = np.meshgrid(np.arange(-half, half + 1), np.arange(-half, half + 1))
    w = np.exp(-0.5 * (k**2 + l**2) / centre**2) if centre > 0 else np.ones_like(img)
    if similarity > 0 and img.std() > 0:
        w = w * np.exp(-0.5 * ((mean - mean[half, half]) / (similarity * img.std())) ** 2)
    return w.ravel()


class TemplateGradients:
    """Central-difference gradients of an image and LSM's template samples: `at(x, y, A)` gives
    the offsets (k, l), the gradients mapped through the affine A (A^-T (g_k, g_l), LSM's Jacobian)
    and the grey values of the (2 half + 1)^2 pixels around the pixel centre (x, y)."""

    def __init__(self, img, half):
        self.img = np.asarray(img, float)
        self.gk, self.gl = np.zeros_like(self.img), np.zeros_like(self.img)
        self.gk[:, 1:-1] = 0.5 * (self.img[:, 2:] - self.img[:, :-2])
        self.gl[1:-1] = 0.5 * (self.img[2:] - self.img[:-2])
        self.k, self.l = (v.ravel() for v in np.meshgrid(np.arange(-half, half + 1.0), np.arange(-half, half + 1.0)))

    def at(self, x, y, a):
        ii = (y - 0.5 + self.l).astype(int)
        jj = (x - 0.5 + self.k).astype(int)
        gx, gy = np.linalg.inv(a).T @ np.vstack([self.gk[ii, jj], self.gl[ii, jj]])
        return self.k, self.l, gx, gy, self.img[ii, jj]


class Scene:
    def __init__(self, paths, first="HRG", second="HRS1"):
        """`paths`: simulate_scene's paths of SceneConfig.small() (the `small_scene` fixture)."""
        self.paths = paths
        self.names = (first, second)
        self.image1 = paths["images"][first]["imagery"]
        self.image2 = paths["images"][second]["imagery"]
        self.model1 = sensors.load(paths["images"][first]["metadata"])
        self.model2 = sensors.load(paths["images"][second]["metadata"])
        self.truth1 = sensors.load(paths["truth_metadata"][first])
        self.truth2 = sensors.load(paths["truth_metadata"][second])
        self.dsm = read_dem(paths["dsm"])
        lo, hi = self.dsm.height_range
        self.height_range = (lo - 100.0, hi + 100.0)
        ds = gdal.Open(str(paths["classes"]))
        self.classes = ds.ReadAsArray()
        self.class_gt = ds.GetGeoTransform()
        ortho = gdal.Open(str(paths["orthoimage"])).ReadAsArray().astype(float)
        m1, m2 = ndimage.uniform_filter(ortho, 19), ndimage.uniform_filter(ortho * ortho, 19)
        self.ground_std = np.sqrt(np.maximum(m2 - m1 * m1, 0.0))  # 95 m: a 19 px HRG template

    def _cell(self, lon, lat):
        gt = self.class_gt
        i = np.clip(((lat - gt[3]) / gt[5]).astype(int), 0, self.classes.shape[0] - 1)
        j = np.clip(((lon - gt[0]) / gt[1]).astype(int), 0, self.classes.shape[1] - 1)
        return i, j

    def truth_model(self, name):
        """The truth model of any image of the triplet ("HRG", "HRS1", "HRS2")."""
        return sensors.load(self.paths["truth_metadata"][name])

    def truth(self, x1, y1, model2=None):
        """(x2, y2, class) of image-1 points (in image 2, or in the image of truth model2)."""
        lon, lat, h = self.truth1.image_to_dem(np.asarray(x1, float), np.asarray(y1, float), self.dsm)
        x2, y2 = (model2 or self.truth2).ground_to_image(lon, lat, h)
        return np.asarray(x2), np.asarray(y2), self.classes[self._cell(lon, lat)]

    def lattice_nodes(self, margin=12):
        """Region growing's lattice nodes (default GrowParams) of image 1 whose template lies inside
        image 2 (`margin` px from its border): x1, y1, class."""
        lattice = Lattice(self.model1.size, GrowParams())
        n, m = np.meshgrid(np.arange(lattice.ncols), np.arange(lattice.nrows))
        x1, y1 = lattice.position(m.ravel(), n.ravel())
        x2, y2, cls = self.truth(x1, y1)
        c2, r2 = self.model2.size
        inside = (x2 > margin) & (x2 < c2 - margin) & (y2 > margin) & (y2 < r2 - margin)
        return x1[inside], y1[inside], cls[inside]

    def texture(self, x1, y1):
        """Ground radiance std (DN) over the template footprint of image-1 points."""
        lon, lat, _ = self.truth1.image_to_dem(np.asarray(x1, float), np.asarray(y1, float), self.dsm)
        return self.ground_std[self._cell(lon, lat)]

    def matchable_precision(self, x1, y1, noise_free, noise_dn=1.0, params=None):
        """Noise-only precision of LSM (px of image 2, the error ellipse's semi-major axis) at
        image-1 points: the covariance of the least-squares position from the texture and the
        image noise alone, as if the model fitted exactly; what any least-squares matcher with
        this template can report there at best. `noise_free`: simulate_scene paths of the same
        scene with noise 0 (the same rendering without the noise draw), whose images give the
        Jacobian. The pair is seen as region growing sees it (resolution.adapt_resolution
        low-passes the finer image, here image 1); the Jacobian J is LSM's (8 parameters, template
        gradients through the models' affine A). With Q = (J'J)^-1 the covariance is Q (M1 + M2) Q:
        image 1's raw white noise sigma^2 (noise_dn^2 + 1/12 quantisation, in DN) through the
        low-pass h gives M1 = sigma^2 (h * J)'(h * J) (the columns of J zero-padded and filtered:
        the smoothed noise is correlated over the template); image 2's, repeated on the 1 / |det A|
        template samples inside one coarser pixel, M2 = sigma^2 rep J'J."""
        params = params or GrowParams()
        pair = adapt_resolution(
            *(Image(noise_free["images"][name]["imagery"]) for name in self.names),
            self.model1,
            self.model2,
            params,
            self.height_range,
        )
        assert not isinstance(pair[1], Smoothed), "image 2 finer than image 1: not modelled"
        sigma = pair[0].sigma if isinstance(pair[0], Smoothed) else (0.0, 0.0)
        half = params.template // 2
        side, pad = 2 * half + 1, int(4 * max(sigma)) + 2
        grads = TemplateGradients(pair[0].read(0, 0, *pair[0].size)[0], half)
        x1, y1 = np.asarray(x1, float), np.asarray(y1, float)
        _, _, a1, a2, a4, a5 = local_affine(self.model1, self.model2, x1, y1, 0.5 * sum(self.height_range))
        sigma2 = noise_dn**2 + 1.0 / 12.0
        out = np.empty(len(x1))
        for p in range(len(x1)):
            a = np.array([[a1[p], a2[p]], [a4[p], a5[p]]])
            k, l, gx, gy, grey = grads.at(x1[p], y1[p], a)
            jac = np.column_stack([gx, gx * k, gx * l, gy, gy * k, gy * l, np.ones_like(gx), grey])
            padded = np.zeros((8, side + 2 * pad, side + 2 * pad))
            padded[:, pad : pad + side, pad : pad + side] = jac.T.reshape(8, side, side)
            hj = ndimage.gaussian_filter(padded, (0.0, *sigma), mode="constant", truncate=4.0).reshape(8, -1)
            q = np.linalg.inv(jac.T @ jac)
            rep = max(1.0, 1.0 / abs(np.linalg.det(a)))
            cov = sigma2 * q @ (hj @ hj.T + rep * (jac.T @ jac)) @ q
            out[p] = np.sqrt(np.linalg.eigvalsh(cov[np.ix_([0, 3], [0, 3])]).max())
        return out

    def area_truth(self, records, half=9, model2=None, support=(0.0, 0.0)):
        """(x2, y2) an ideal area matcher gives for matched records (module docstring); model2 as
        in `truth`; `support` = (centre_sigma, similarity) of MPGC's support weights on the template
        samples (mpgc.py; (0, 0): uniform)."""
        grads = TemplateGradients(gdal.Open(str(self.image1)).ReadAsArray(), half)
        k, l = grads.k, grads.l
        n = len(records)
        tx, ty, _ = self.truth((records["x1"][:, None] + k).ravel(), (records["y1"][:, None] + l).ravel(), model2)
        tx, ty = tx.reshape(n, -1), ty.reshape(n, -1)
        out = np.empty((n, 2))
        for p in range(n):
            a = np.array([[float(records[q][p]) for q in ("a1", "a2")], [float(records[q][p]) for q in ("a4", "a5")]])
            _, _, gx, gy, f = grads.at(records["x1"][p], records["y1"][p], a)
            w = support_reference(f, half, *support)
            jac = np.column_stack([gx, gx * k, gx * l, gy, gy * k, gy * l]) * np.sqrt(w)[:, None]
            sol = np.linalg.lstsq(jac, (gx * tx[p] + gy * ty[p]) * np.sqrt(w), rcond=None)[0]
            out[p] = sol[0], sol[3]
        return out[:, 0], out[:, 1]
