"""Matching parameters with the papers' defaults (Hofmann et al.; Kornus et al. 2006, section 3.3).
Where a default departs from the papers or a switch is off, the reason is measured in
docs/validation.md."""
from dataclasses import dataclass

from ..errors import InputError


@dataclass
class LsmParams:
    """Least-squares matching: window and the acceptance criteria of a matched point."""

    template: int = 19          # window size, px (odd)
    max_iterations: int = 10    # iterations < maximum
    convergence: float = 0.01   # px: stop when the position update is smaller
    rho_min: float = 0.6        # correlation coefficient > rho_min (0.7 in Kornus et al. for DEM points)
    max_ellipse: float = 0.1    # px: semi-major axis of the error ellipse < threshold (the papers' value)
    max_shift: float = 2.5      # px: shift from the initial values < threshold

    @property
    def widest(self):
        """The largest window a match may use (px)."""
        return self.template

    def check(self):
        """Raise InputError for values no matcher can use."""
        if self.template < 5 or self.template % 2 == 0:
            raise InputError(f"the template size must be an odd number of at least 5 pixels, got {self.template}")
        if not 0.0 < self.rho_min < 1.0:
            raise InputError(f"rho_min must lie between 0 and 1, got {self.rho_min}")
        if self.max_iterations < 1 or self.max_ellipse <= 0 or self.max_shift <= 0 or self.convergence <= 0:
            raise InputError("iterations, ellipse, shift and convergence thresholds must be positive")
        return self


@dataclass
class GrowParams(LsmParams):
    """Region growing: neighbour distance STEP and the tiling of the reference image."""

    step: int = 10              # px between a point and its four neighbours (10-15 in Hofmann et al.)
    tile: int = 1024            # px, square tiles of the reference image, grown independently
    # neighbours' initial affine shape: the sensor models' local affine of the tile (True), or the
    # popped point's estimate as in Hofmann et al. (False), which drifts along growth paths
    model_affine: bool = True
    # resolution adaptation (Kornus et al. 2006, 3.3: image scales adapted by scale factors): the finer
    # image is low-passed to the coarser one's footprint (region_growing.adapt_resolution); the PSF is
    # "sensor" (each instrument's own, region_growing.SENSOR_PSF; unknown ones fall back to "pixel"),
    # "pixel" (Gaussian of psf_sigma px of each image's own pixels) or "off"
    psf: str = "sensor"
    psf_sigma: float = 0.5
    # second, wider window (odd px; 0 = off) for a node whose LSM at `template` fails inside the images:
    # less noise in the precision, more relief inside the window; the point must still pass every criterion
    wide_template: int = 0
    # px of image 1: cell of the second round of automatic seeds (region_growing.py); 0 = one round
    reseed_cell: int = 16
    # MPGC refinement of the group 3 points with support weights (refinement.py: SUPPORT_CENTRE,
    # SUPPORT_SIMILARITY), so each match measures the surface around its template centre (for DEMs)
    support_weights: bool = False

    @property
    def widest(self):
        return max(self.template, self.wide_template)

    def check(self):
        super().check()
        if self.step < 1 or self.tile < 4 * self.step:
            raise InputError(f"STEP must be >= 1 and the tile at least 4 STEP, got step {self.step}, tile {self.tile}")
        if not 0.0 <= self.psf_sigma <= 5.0:
            raise InputError(f"psf_sigma must lie between 0 (off) and 5 px, got {self.psf_sigma}")
        if self.wide_template and (self.wide_template % 2 == 0 or self.wide_template <= self.template):
            raise InputError(f"the wide template must be 0 (off) or an odd size larger than the template "
                             f"({self.template} px), got {self.wide_template}")
        if self.reseed_cell and self.reseed_cell < 3:
            raise InputError(f"the reseed cell must be 0 (off) or at least 3 pixels, got {self.reseed_cell}")
        if self.psf not in ("sensor", "pixel", "off"):
            raise InputError(f"psf must be 'sensor', 'pixel' or 'off', got {self.psf!r}")
        return self
