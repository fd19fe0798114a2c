"""Settings of dense matching (the "dense" strategy of pushbroom:matchpoints)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import InputError
from ..matching.params import GrowParams
from .sgm import SgmParams


@dataclass
class DenseParams:
    """tile: image-1 tile size (px), each tile one task; step: lattice step of the points (image-1 px, 1:
    every pixel); grid_step: epipolar grid node spacing (epipolar px); max_spread: the largest spread (px)
    of the four disparities a lattice node is interpolated from; sgm: census and SGM settings; lsm: LSM
    refinement in the original images (refine.py) with a `template` px window, kept within `max_shift` px
    of the dense position, with LSM's robust weighting where `robust`, a node the template fails at tried again
    with a `wide_template` px window (0: none), and a node whose refined neighbours' moves are systematic, beyond
    `bias_bound` times their spread and beyond `census_error` times the census's share of LSM's ellipse, keeping
    its semi-global positions in every pair (refine.biased; bias_bound 0: no such test); mpgc: a
    triplet's three-ray points refined again by MPGC in both search images at once (dense_strategy.py)."""

    tile: int = 512
    step: int = 1
    grid_step: int = 16
    max_spread: float = 1.0
    sgm: SgmParams = field(default_factory=SgmParams)
    lsm: bool = True
    template: int = 19
    wide_template: int = 31
    max_shift: float = 1.0
    robust: bool = True
    bias_bound: float = 0.8
    census_error: float = 1.5
    mpgc: bool = False

    def refinement(self) -> GrowParams:
        """LSM's settings of the refinement (refine.refine_positions): region growing's acceptance criteria, the
        template, the largest shift, the robust weights and the wide window, which is not tried for a node the
        template moved beyond the largest shift (studies/README.md#dense_wide)."""
        return GrowParams(
            template=int(self.template),
            max_shift=float(self.max_shift),
            robust=bool(self.robust),
            wide_template=int(self.wide_template),
            wide_beyond_shift=False,
        )

    def check(self) -> DenseParams:
        """Raise InputError for settings dense matching cannot use."""
        if not 64 <= int(self.tile) <= 4096:
            raise InputError(f"the dense matching tile must be 64 to 4096 px, got {self.tile}")
        if not 1 <= int(self.step) <= int(self.tile):
            raise InputError(f"the dense lattice step must be 1 px to the tile size, got {self.step}")
        if not 4 <= int(self.grid_step) <= 64:
            raise InputError(f"the epipolar grid step must be 4 to 64 px, got {self.grid_step}")
        if not self.max_spread > 0:
            raise InputError("the disparity spread of a lattice node must be positive")
        if not 1 <= int(self.sgm.census_radius) <= 3:
            raise InputError(
                f"the census radius must be 1 to 3 px (a 3 x 3 to 7 x 7 window: 64 bits at most), "
                f"got {self.sgm.census_radius}"
            )
        if self.template < 5 or self.template % 2 == 0:
            raise InputError(f"the refinement template must be an odd number of at least 5 px, got {self.template}")
        if not self.max_shift > 0:
            raise InputError("the refinement's largest shift must be positive")
        if not self.bias_bound >= 0:
            raise InputError(f"the refinement's bias bound must be 0 (off) or positive, got {self.bias_bound}")
        if not self.census_error >= 0:
            raise InputError(f"the bias test's census error factor must be 0 or positive, got {self.census_error}")
        self.refinement().check()  # the wide template's rule
        if not 0 < self.sgm.p1 < self.sgm.p2:
            raise InputError(f"the SGM penalties must satisfy 0 < P1 < P2, got {self.sgm.p1}, {self.sgm.p2}")
        return self
