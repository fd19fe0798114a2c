"""The bundle adjustment of algorithms/adjustment/bundle.py posed for scipy.optimize.least_squares
(an independent formulation: the reference of the benchmark and of test_bundle_scipy_reference.py).

Unknowns z = (the free orientation unknowns of parameters.OrientationParameters, in its units;
then per point dE, dN, dU in metres from its starting value, lon = lon0 + dE / e0, lat = lat0 +
dN / n0, h = h0 + dU with e0, n0 = geodesy.metres_per_degree(lat0, h0)). Residuals: per image
measurement (computed - measured) / sigma for col and row (models' ground_to_image); per control
point (dE, dN, dU) minus its observed offset, over its ground sigmas (the same as bundle.py's
ground misclosures to ~1e-7 relative: its metres per degree at the current point, here at the start).
Starting values as `adjust`: orientation 0, points from bundle.start_points (control points at their
observations, the others intersected). Jacobian analytic from the models' `partials` (d_corrections
mapped by the parameters' jacobian_map, d_ground over e0, n0), a scipy.sparse CSR matrix; solved by
method="trf" with tr_solver="lsmr"."""

import numpy as np
from scipy import sparse
from scipy.optimize import least_squares

from pushbroom.algorithms.adjustment.bundle import start_points
from pushbroom.algorithms.adjustment.parameters import OrientationParameters
from pushbroom.algorithms.geodesy import metres_per_degree


class ScipyBundle:
    """The problem of adjust(models, observations, free, names, height) (module docstring)."""

    def __init__(self, models, observations, free, names=None, height=0.0):
        self.params = OrientationParameters(models, names)
        self.params.free = self.params.select(free)
        obs = observations.subset(observations.points["role"] != "check")
        lon, lat, h, usable = start_points(models, obs, height)
        self.obs = obs.subset(usable)
        self.lon0, self.lat0, self.h0 = lon[usable], lat[usable], h[usable]
        self.e0, self.n0 = metres_per_degree(self.lat0, self.h0)
        self.nfree = int(self.params.free.sum())
        p, m = self.obs.points, self.obs.measurements
        self.control = np.flatnonzero(p["role"] == "control")
        self.ground_sigma = np.column_stack([p["sigma_e"], p["sigma_n"], p["sigma_h"]])[self.control]
        self.ground_observed = np.column_stack(
            [(p["lon"] - self.lon0) * self.e0, (p["lat"] - self.lat0) * self.n0, p["h"] - self.h0]
        )[self.control]
        self.by_image = {i: np.flatnonzero(m["image_id"] == i) for i in np.unique(m["image_id"])}
        self.free_maps = {i: self.params.jacobian_map(i)[:, self.params.free] for i in self.by_image}
        # as adjust: the exterior orientation's partials only where one of its coefficients is free
        self.exterior = {
            i: bool(np.any(f[: models[i].EXTERIOR_COEFFICIENTS] != 0.0)) for i, f in self.free_maps.items()
        }

    @property
    def size(self):
        return self.nfree + 3 * len(self.obs.points)

    def points(self, z):
        """lon, lat, h of the points at z."""
        d = z[self.nfree :].reshape(-1, 3)
        return self.lon0 + d[:, 0] / self.e0, self.lat0 + d[:, 1] / self.n0, self.h0 + d[:, 2]

    def _apply(self, z):
        x = np.zeros(len(self.params))
        x[self.params.free] = z[: self.nfree]
        self.params.apply(x)

    def residuals(self, z):
        """Weighted residuals: (computed - measured) / sigma of every measurement (col, row), then
        the control points' (dE, dN, dU) - observed over their sigmas."""
        self._apply(z)
        lon, lat, h = self.points(z)
        m = self.obs.measurements
        image = np.empty((len(m), 2))
        for i, k in self.by_image.items():
            p = m["point"][k]
            image[k] = np.column_stack(self.params.models[i].ground_to_image(lon[p], lat[p], h[p]))
        image = (image - np.column_stack([m["col"], m["row"]])) / m["sigma"][:, None]
        ground = (z[self.nfree :].reshape(-1, 3)[self.control] - self.ground_observed) / self.ground_sigma
        return np.concatenate([image.ravel(), ground.ravel()])

    def jacobian(self, z, *_):
        """d residuals / dz (CSR): image rows from `partials`, ground rows 1 / sigma."""
        self._apply(z)
        lon, lat, h = self.points(z)
        m = self.obs.measurements
        rows, cols, values = [], [], []
        for i, k in self.by_image.items():
            p = m["point"][k]
            d = self.params.models[i].partials(lon[p], lat[p], h[p], exterior=self.exterior[i])
            weight = 1.0 / m["sigma"][k]
            row = 2 * k[:, None] + np.arange(2)  # (n, 2)
            orientation = d["d_corrections"] @ self.free_maps[i] * weight[:, None, None]  # (n, 2, nfree)
            used = np.flatnonzero(np.any(self.free_maps[i] != 0.0, axis=0))
            rows.append(np.repeat(row[:, :, None], used.size, axis=2).ravel())
            cols.append(np.broadcast_to(used, orientation[:, :, used].shape).ravel())
            values.append(orientation[:, :, used].ravel())
            ground = d["d_ground"] / np.column_stack([self.e0[p], self.n0[p], np.ones(p.size)])[:, None, :]
            rows.append(np.repeat(row[:, :, None], 3, axis=2).ravel())
            cols.append((self.nfree + 3 * p[:, None, None] + np.arange(3)).repeat(2, axis=1).ravel())
            values.append((ground * weight[:, None, None]).ravel())
        first = 2 * len(m) + np.arange(3 * self.control.size)
        rows.append(first)
        cols.append((self.nfree + 3 * self.control[:, None] + np.arange(3)).ravel())
        values.append((1.0 / self.ground_sigma).ravel())
        shape = (2 * len(m) + 3 * self.control.size, self.size)
        return sparse.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape=shape)

    def solve(self, tolerance=1e-12):
        """least_squares from the starting values; returns (orientation unknowns, lon, lat, h,
        scipy's OptimizeResult). The models are left with the solution."""
        result = least_squares(
            self.residuals,
            np.zeros(self.size),
            jac=self.jacobian,
            method="trf",
            tr_solver="lsmr",
            x_scale="jac",
            ftol=tolerance,
            xtol=tolerance,
            gtol=tolerance,
            tr_options={"atol": tolerance, "btol": tolerance},
        )
        self._apply(result.x)
        return (result.x[: self.nfree].copy(), *self.points(result.x), result)
