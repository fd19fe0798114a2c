"""A fourth matching strategy, as small as the interface allows: the whole of what adding one takes
(docs/architecture.md, "A matching strategy"). Importing this module registers it.

"toy_grid" does not match: it places a point on every `step`-th pixel of the reference image and takes its
positions in the other images from the sensor models at the middle of the height range. On error-free models
over flat terrain at that height, those are the true conjugates."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pushbroom.algorithms.errors import InputError
from pushbroom.algorithms.matching.match_stats import MatchStats
from pushbroom.algorithms.matching.pair_geometry import predict
from pushbroom.algorithms.matching.points import COMB_A, COMB_B, OBS_DTYPE, POINT_DTYPE, MultiPoints
from pushbroom.algorithms.matching.strategy import MatchingStrategy, TilePlan, register
from pushbroom.algorithms.matching.tiled_rounds import save_work
from pushbroom.algorithms.tiling import tile_grid


@dataclass
class ToySettings:
    step: int = 20  # px between the points in the reference image
    tile: int = 256  # px: square tiles of the reference image

    def check(self) -> ToySettings:
        if self.step < 1 or self.tile < self.step:
            raise InputError(f"the toy grid needs 1 <= step <= tile, got {self.step}, {self.tile}")
        return self


@register
class ToyGrid(MatchingStrategy):
    """The models' predictions on a grid of the reference image (module docstring)."""

    name = "toy_grid"
    settings_type = ToySettings
    spacing_setting = "step"

    @classmethod
    def plan(cls, stereo, settings, feedback) -> TilePlan:
        boxes = tile_grid(stereo.models[0].size, settings.tile)
        return TilePlan((stereo.without_loader(), settings), boxes, [0] * len(boxes))

    @staticmethod
    def match_tile(job: Any, index: int, box: Any, out: str, quota: int) -> dict[str, Any]:
        stereo, settings = job
        x0, y0, x1, y1 = box
        gy, gx = np.mgrid[y0 + 0.5 : y1 : settings.step, x0 + 0.5 : x1 : settings.step]
        x, y = gx.ravel(), gy.ravel()
        n, m = len(x), len(stereo)
        points = np.zeros(n, POINT_DTYPE)
        points["id"] = np.arange(1, n + 1)
        points["group"] = 1 if m == 2 else 2
        points["flags"] = COMB_A | (COMB_B if m == 3 else 0)
        points["rho_min"] = points["rho_a"] = 1.0
        points["rho_b"] = 1.0 if m == 3 else np.nan
        points["rho_c"] = points["dx"] = points["dy"] = np.nan
        obs = np.zeros(n * m, OBS_DTYPE)
        obs["point_id"] = np.repeat(points["id"], m)
        obs["image_id"] = np.tile(stereo.ids, n)
        obs["rho"] = np.nan
        for k in range(m):
            col, row = (x, y) if k == 0 else predict(stereo.models[0], stereo.models[k], x, y, stereo.heights.mean)
            obs["col"][k::m], obs["row"][k::m] = col, row
        save_work(out, MultiPoints(points, obs[np.lexsort((obs["image_id"], obs["point_id"]))]))
        return {"points": n}

    @classmethod
    def stats(cls, job, rounds, feedback) -> MatchStats:
        return MatchStats(cls.name, list(job[0].ids), int(sum(rounds.counts)))
