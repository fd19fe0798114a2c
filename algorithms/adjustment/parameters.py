"""Orientation unknowns of the block adjustment (Kornus et al. 2006, section 3.4, eq. 2-4).

Rigorous SPOT images: correction polynomials of degree 0-3. The exterior ones (ECEF position
X, Y, Z in m; yaw, pitch, roll in rad) are common to a trajectory, i.e. to all images taken by one
satellite within one pass, and run over the normalised time tau = (t - t_ref) / s (t absolute,
t_ref the trajectory's mean image centre time, s = Corrections.time_scale). Each image holds its
own corrections over its own tau_i = (t - t_c,i) / s, so a trajectory coefficient vector g maps
to the image's by re-expanding about t_c,i: with d = (t_c,i - t_ref) / s,
    sum_j g_j (tau_i + d)^j = sum_k (sum_{j>=k} C(j, k) d^(j-k) g_j) tau_i^k.
The look-angle corrections (psi_x, psi_y over (p - p_c) / 1000) belong to each image (sensor).

Lagrange model (model="lagrange"; Heipke et al. 1992, section 3): per trajectory n orientation
images at times t_0 < .. < t_(n-1), equally spaced from the centre time of the first line its
images cover to that of the last (n = 4 by default: ~2000 lines apart on a 6000-line SPOT 1-4
scene). Unknowns: the corrections of X, Y, Z, yaw, pitch, roll at each orientation image
("pass A pitch@2", nodes numbered from 0 in time order) and an offset of the position per
trajectory ("pass A offset_X"): position correction at node k = offset + delta_k (delta_k: the
"X@k" unknowns). Any line's correction is the Lagrange polynomial through the node values,
    f(t) = sum_k v_k prod_(m != k) (t - t_m) / (t_k - t_m),
of degree n - 1 <= 3, i.e. one polynomial in time: image i's Corrections coefficients over its own
tau_i are V_i^-1 v with V_i[k, j] = tau_k^j, tau_k = (t_k - t_c,i) / s (`lagrange_matrix`), so
the sensor model is unchanged. More than 4 orientation images would need a piecewise cubic (each
line from its 4 nearest nodes), which one Corrections polynomial cannot hold: refused
(InputError). The header positions enter as observations with high relative and low absolute
accuracy (Heipke et al. 1992, section 4.1.1): `default_priors` delta_k = 0 +- 1 m, offset = 0 +- 1000 m (bundle.adjust
merges the user's priors over them). Look-angle (and RPC bias) unknowns are the same in both models.

RPC images: an image-space affine bias per image (the RpcModel's `bias`, see sensors/rpc.py):
col += A0 + A1 u + A2 v, row += B0 + B1 u + B2 v, u, v = image coordinates / 1000 about the centre;
"shift" frees A0, B0, "drift" also A2, B2 (along-track drift), "affine" all six.

The unknowns are increments to the supplied corrections, so a block adjusted twice continues from
the first adjustment's result."""

from dataclasses import dataclass
from math import comb

import numpy as np

from ..errors import InputError
from ..sensors.rpc import RpcModel
from ..sensors.spot import SpotModel

EXTERIOR = ("X", "Y", "Z", "yaw", "pitch", "roll")
OFFSETS = ("offset_X", "offset_Y", "offset_Z")
MODELS = ("polynomial", "lagrange")
#: select patterns lagrange:<set> of the Lagrange model
LAGRANGE_SETS = {"attitude": EXTERIOR[3:], "position": EXTERIOR[:3], "offset": OFFSETS, "all": EXTERIOR + OFFSETS}
#: orientation images per trajectory (Heipke et al. 1992, section 3: four, about 2000 lines apart); at most 4
#: (module docstring)
ORIENTATION_IMAGES = 4
#: prior sigmas (m) of the Lagrange model: header positions good to 1 m relative, 1000 m absolute (Heipke et al.
#: 1992, section 4.1.1)
LAGRANGE_PRIORS = {"lagrange:position": 1.0, "lagrange:offset": 1000.0}
LOOK = ("psi_x", "psi_y")
BIAS = ("A0", "A1", "A2", "B0", "B1", "B2")
BIAS_SETS = {"shift": ("A0", "B0"), "drift": ("A0", "A2", "B0", "B2"), "affine": BIAS}
#: a trajectory: one mission, image centre times within this many seconds
PASS_SECONDS = 600.0
#: display units of the parameters (value multiplied by the factor)
UNITS = {
    "X": ("m", 1.0),
    "Y": ("m", 1.0),
    "Z": ("m", 1.0),
    "yaw": ("urad", 1e6),
    "pitch": ("urad", 1e6),
    "roll": ("urad", 1e6),
    "psi_x": ("urad", 1e6),
    "psi_y": ("urad", 1e6),
    "offset_X": ("m", 1.0),
    "offset_Y": ("m", 1.0),
    "offset_Z": ("m", 1.0),
}


def shift_matrix(d):
    """(4, 4) M with image coefficients = M @ trajectory coefficients, M[k, j] = C(j, k) d^(j-k)."""
    m = np.zeros((4, 4))
    for j in range(4):
        for k in range(j + 1):
            m[k, j] = comb(j, k) * d ** (j - k)
    return m


def lagrange_matrix(node_times, centre_time, time_scale):
    """(4, n) W with an image's correction coefficients over tau = (t - centre_time) / time_scale
    = W @ the values at the n <= 4 nodes: W = V^-1 (zero rows below degree n - 1), V[k, j] = tau_k^j."""
    tau = (np.asarray(node_times, float) - centre_time) / time_scale
    n = tau.size
    w = np.zeros((4, n))
    w[:n] = np.linalg.inv(np.vander(tau, n, increasing=True))
    return w


@dataclass
class Parameter:
    name: str  # e.g. "pass 1 pitch_1", "HRS2 psi_y_0", "pass 1 roll@2"
    owner: str  # trajectory or image label
    kind: str  # X .. roll, psi_x, psi_y, A0 .. B2, offset_X .. offset_Z
    degree: int  # polynomial degree (0 for bias, offset and orientation-image terms)
    node: int = -1  # orientation image of the Lagrange model (-1: none)


def _epoch_seconds(orientation):
    return (orientation.epoch - np.datetime64("2000-01-01T00:00:00", "ns")) / np.timedelta64(1, "s")


def _absolute_time(model):
    return _epoch_seconds(model.orientation) + model.orientation.centre_time


def line_time(model, row):
    """Time (s since 2000-01-01, as the trajectories' node_times) of image row `row` of a SPOT model."""
    return _epoch_seconds(model.orientation) + model.orientation.row_time(row)


def node_times(models, count=ORIENTATION_IMAGES):
    """Times of `count` orientation images equally spaced from the first to the last line centre
    the SPOT `models` (one trajectory) cover."""
    ends = [line_time(m, row) for m in models for row in (0.5, m.orientation.nrows - 0.5)]
    return np.linspace(min(ends), max(ends), count)


class OrientationParameters:
    """All orientation unknowns of a block and their map to each image's model corrections.

    models: {image_id: model}; names: {image_id: label}. `jacobian_map(image_id)` is the (32, n)
    (SPOT) or (6, n) (RPC) matrix T with image coefficients increment = T @ x, x the vector of all
    unknowns (free or fixed). `free` is a boolean mask (default: nothing free). model: "polynomial"
    or "lagrange" (module docstring) with `orientation_images` (2-4) per trajectory."""

    def __init__(self, models, names=None, model="polynomial", orientation_images=ORIENTATION_IMAGES):
        if model not in MODELS:
            raise InputError(f"the orientation model must be one of {', '.join(MODELS)}, not {model!r}")
        if model == "lagrange" and orientation_images not in (2, 3, 4):
            raise InputError(
                f"{orientation_images} orientation images per trajectory: the Lagrange model takes 2 "
                "to 4 (more would need a piecewise polynomial that the correction polynomials of the "
                "sensor model cannot hold); use 4, one cubic over the whole trajectory"
            )
        self.model = model
        self.models = dict(models)
        self.names = {i: (names or {}).get(i, f"image {i}") for i in self.models}
        self.parameters = []
        self._maps = {}
        spot = {i: m for i, m in self.models.items() if isinstance(m, SpotModel)}
        other = [i for i, m in self.models.items() if not isinstance(m, (SpotModel, RpcModel))]
        if other:
            raise InputError(
                f"{self.names[other[0]]}: its model {self.models[other[0]]!r} has no adjustable "
                "orientation (SPOT rigorous and RPC models are supported)"
            )
        self.trajectories = self._trajectories(spot)
        lagrange = model == "lagrange"
        #: per trajectory, the times of its orientation images (Lagrange model; s, as _absolute_time)
        self.node_times = [
            node_times([spot[i] for i in members], orientation_images) if lagrange else None
            for members in self.trajectories
        ]
        cols = {}
        for t, members in enumerate(self.trajectories):
            label = "pass " + "+".join(self.names[i] for i in members)
            if lagrange:
                cols[("traj", t)] = self._add(
                    label, [(k, j) for k in EXTERIOR for j in range(orientation_images)], nodes=True
                )
                self._add(label, [(k, 0) for k in OFFSETS])
            else:
                cols[("traj", t)] = self._add(label, [(k, j) for k in EXTERIOR for j in range(4)])
        for i in spot:
            cols[("look", i)] = self._add(self.names[i], [(k, j) for k in LOOK for j in range(4)])
        for i, m in self.models.items():
            if isinstance(m, RpcModel):
                cols[("bias", i)] = self._add(self.names[i], [(k, 0) for k in BIAS])
        n = len(self.parameters)
        for t, members in enumerate(self.trajectories):
            t_ref = np.mean([_absolute_time(spot[i]) for i in members])
            for i in members:
                c = spot[i].orientation.corrections
                tmap = np.zeros((32, n))
                base = cols[("traj", t)]
                if lagrange:
                    w = lagrange_matrix(self.node_times[t], _absolute_time(spot[i]), c.time_scale)
                    nn = orientation_images
                    for k in range(6):
                        tmap[4 * k : 4 * k + 4, base + nn * k : base + nn * k + nn] = w
                    for k in range(3):  # the offset is a constant: degree 0 of X, Y, Z
                        tmap[4 * k, base + 6 * nn + k] = 1.0
                else:
                    m = shift_matrix((_absolute_time(spot[i]) - t_ref) / c.time_scale)
                    for k in range(6):
                        tmap[4 * k : 4 * k + 4, base + 4 * k : base + 4 * k + 4] = m
                tmap[24:32, cols[("look", i)] : cols[("look", i)] + 8] = np.eye(8)
                self._maps[i] = tmap
        for i, m in self.models.items():
            if isinstance(m, RpcModel):
                tmap = np.zeros((6, n))
                tmap[:, cols[("bias", i)] : cols[("bias", i)] + 6] = np.eye(6)
                self._maps[i] = tmap
        self.initial = {i: self._coefficients(m).copy() for i, m in self.models.items()}
        self.free = np.zeros(n, bool)
        self.prior_weights = np.zeros(n)  # 1 / sigma^2 of prior observations x = 0 (bundle.prior_sigmas)

    def _add(self, owner, terms, nodes=False):
        """Append parameters (kind, degree), or with `nodes` (kind, orientation image); returns the first's index."""
        start = len(self.parameters)
        for kind, j in terms:
            if nodes:
                self.parameters.append(Parameter(f"{owner} {kind}@{j}", owner, kind, 0, j))
            else:
                name = f"{owner} {kind}" if kind in BIAS + OFFSETS else f"{owner} {kind}_{j}"
                self.parameters.append(Parameter(name, owner, kind, j))
        return start

    @property
    def default_priors(self):
        """{pattern: sigma} the model brings: the Lagrange model's header positions (LAGRANGE_PRIORS)."""
        return dict(LAGRANGE_PRIORS) if self.model == "lagrange" and self.trajectories else {}

    def _trajectories(self, spot):
        """Image ids grouped by (mission, pass): centre times within PASS_SECONDS."""
        groups = []
        for i in sorted(spot, key=lambda i: (spot[i].orientation.mission, _absolute_time(spot[i]))):
            o, t = spot[i].orientation, _absolute_time(spot[i])
            last = groups[-1] if groups else None
            if (
                last
                and spot[last[-1]].orientation.mission == o.mission
                and abs(t - _absolute_time(spot[last[-1]])) < PASS_SECONDS
            ):
                last.append(i)
            else:
                groups.append([i])
        return groups

    def __len__(self):
        return len(self.parameters)

    def jacobian_map(self, image_id):
        return self._maps[image_id]

    @staticmethod
    def _coefficients(model):
        if isinstance(model, SpotModel):
            c = model.orientation.corrections
            return np.concatenate([np.ravel(c.position), np.ravel(c.attitude), np.ravel(c.look)])
        return np.asarray(model.bias, float).copy()

    def apply(self, x):
        """Set every model's corrections to its initial ones + T @ x."""
        x = np.asarray(x, float)
        for i, m in self.models.items():
            v = self.initial[i] + self._maps[i] @ x
            if isinstance(m, SpotModel):
                c = m.orientation.corrections
                c.position, c.attitude, c.look = v[:12].reshape(3, 4), v[12:24].reshape(3, 4), v[24:].reshape(2, 4)
            else:
                m.bias = v

    def select(self, spec):
        """Free mask from a specification: an iterable of names or patterns. A pattern is
        '<kind>_<degrees>' applied to every owner (e.g. 'psi_x_0', 'pitch_01', 'X_0'), 'look:<deg>'
        ('look:1' frees psi_x/psi_y of degree <= 1 of every image), 'exterior:<deg>', 'bias:<set>'
        (shift, drift, affine), or a full parameter name. Lagrange model: '<kind>@<nodes>' (e.g.
        'pitch@0123', 'X@0'), 'offset_X' .. 'offset_Z', and 'lagrange:<set>' with the sets attitude
        (yaw, pitch, roll at every orientation image), position (X, Y, Z there), offset and all
        (the three), each over every trajectory. Raises InputError for unknown ones."""
        mask = np.zeros(len(self), bool)
        for item in spec:
            item = item.strip()
            if not item:
                continue
            hit = self._match(item)
            if not hit.any():
                lagrange = (
                    "lagrange:attitude|position|offset|all, <kind>@<nodes>, offset_X|Y|Z"
                    if self.model == "lagrange"
                    else "exterior:<degree>, <kind>_<degrees>"
                )
                raise InputError(
                    f"no orientation parameter matches {item!r}; parameters are named like "
                    f"{self.parameters[0].name!r}; patterns: look:<degree>, bias:shift|drift|affine, "
                    f"{lagrange}"
                )
            mask |= hit
        return mask

    def _match(self, item):
        p = self.parameters
        if ":" in item:
            what, arg = item.split(":", 1)
            if what == "bias":
                if arg not in BIAS_SETS:
                    raise InputError(f"bias set must be one of {', '.join(BIAS_SETS)}, not {arg!r}")
                return np.array([q.kind in BIAS_SETS[arg] for q in p])
            if what == "lagrange":
                if arg not in LAGRANGE_SETS:
                    raise InputError(f"Lagrange set must be one of {', '.join(LAGRANGE_SETS)}, not {arg!r}")
                return np.array([q.kind in LAGRANGE_SETS[arg] and (q.node >= 0 or q.kind in OFFSETS) for q in p])
            kinds = {"look": LOOK, "exterior": EXTERIOR}.get(what)
            if kinds is None or not arg.isdigit():
                raise InputError(f"cannot read the parameter pattern {item!r}")
            return np.array([q.kind in kinds and q.node < 0 and q.degree <= int(arg) for q in p])
        if "_" in item and item.rsplit("_", 1)[0] in EXTERIOR + LOOK and item.rsplit("_", 1)[1].isdigit():
            kind, degrees = item.rsplit("_", 1)
            return np.array([q.kind == kind and q.node < 0 and str(q.degree) in degrees for q in p])
        if "@" in item and item.split("@", 1)[0] in EXTERIOR and item.split("@", 1)[1].isdigit():
            kind, nodes = item.split("@", 1)
            return np.array([q.kind == kind and q.node >= 0 and str(q.node) in nodes for q in p])
        if item in OFFSETS:
            return np.array([q.kind == item for q in p])
        return np.array([q.name == item for q in p])

    def label(self, index):
        return self.parameters[index].name

    def max_effects(self, x, height):
        """Largest image displacement (px) each free unknown causes on its own (Kornus et al. 2006, Table 2:
        "maximum effect"): the 3 x 3 grid of image corners, edge midpoints and centre of every
        image it acts on is projected to the ground at `height` with the solution x, then back
        with that unknown alone set to 0."""
        x = np.asarray(x, float)
        self.apply(x)
        grid = {}
        for i, m in self.models.items():
            cols, rows = m.size
            c, r = (v.ravel() for v in np.meshgrid(np.linspace(0, cols, 3), np.linspace(0, rows, 3)))
            grid[i] = (c, r, *m.image_to_ground(c, r, np.full(c.size, float(height))))
        effects = np.full(len(self), np.nan)
        for q in np.flatnonzero(self.free):
            y = x.copy()
            y[q] = 0.0
            self.apply(y)
            effects[q] = max(
                float(np.max(np.hypot(*(np.subtract(self.models[i].ground_to_image(lon, lat, height), (c, r))))))
                for i, (c, r, lon, lat) in grid.items()
                if self._maps[i][:, q].any()
            )
        self.apply(x)
        return effects
