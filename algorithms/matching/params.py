"""Matching parameters with the papers' defaults (Heipke et al. 1992, section 2,
Kornus et al. 2006, section 3.3)."""

from dataclasses import dataclass

from ..errors import InputError

#: Tukey biweight constant (95 % efficiency for Gaussian residuals), in units of the residual scale
TUKEY_C = 4.685


@dataclass
class LsmParams:
    """Least-squares matching: window and the acceptance criteria of a matched point."""

    template: int = 19  # window size, px (odd)
    max_iterations: int = 10  # iterations < maximum
    convergence: float = 0.01  # px: stop when the position update is smaller
    rho_min: float = 0.6  # correlation coefficient > rho_min (0.7 in Kornus et al. 2006 for DEM points)
    # px: semi-major axis of the error ellipse < threshold (Heipke et al. 1992; Kornus et al. 2006);
    # why not wider: docs/validation.md#lsm-error-ellipse-threshold
    max_ellipse: float = 0.1
    max_shift: float = 2.5  # px: shift from the initial values < threshold

    @property
    def widest(self):
        """The largest window a match may use (px)."""
        return self.template

    @property
    def tukey(self):
        """Tukey's constant of LSM's robust weighting (lsm.py), 0: plain least squares."""
        return 0.0

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

    step: int = 10  # px between a point and its four neighbours (10-15 in Heipke et al. 1992)
    tile: int = 1024  # px, square tiles of the reference image, grown independently
    # neighbours' initial affine shape: the sensor models' local affine of the tile (True), or the popped
    # point's estimate as in Heipke et al. 1992 (False); docs/validation.md#region-growing-model-affine
    model_affine: bool = True
    # resolution adaptation (Kornus et al. 2006, section 3.3): the finer image is low-passed to the coarser
    # one's footprint through the models' local affine (resolution.adapt_resolution). psf: "sensor"
    # (each instrument's PSF, resolution.SENSOR_PSF, as Gaussian-equivalent variances; "pixel" where
    # the instrument is unknown), "pixel" (Gaussian of psf_sigma px of each image's pixels; 0.5 px is
    # SPOT's MTF(Nyquist) ~ 0.3) or "off"; docs/validation.md#region-growing-resolution-adaptation
    psf: str = "sensor"
    psf_sigma: float = 0.5
    # odd px, 0 = off: a second, wider window for a node whose LSM at `template` fails inside the images
    # (Kanade and Okutomi's trade of noise against relief); docs/validation.md#region-growing-wide-template
    wide_template: int = 0
    # the wide window also for a node the template moved beyond max_shift (off in the dense refinement, where such
    # a template straddles a height step, which a wider one straddles more; studies/README.md#dense_wide)
    wide_beyond_shift: bool = True
    # px of image 1, 0 = one round: with automatic seeds, a second round of them at the lattice nodes the
    # first round's growth did not try; docs/validation.md#region-growing-second-seed-round
    reseed_cell: int = 16
    # MPGC refinement of the group 3 points with support weights (refinement.SUPPORT_CENTRE,
    # SUPPORT_SIMILARITY): on in the DEM pipeline model; docs/validation.md#mpgc-support-weights
    support_weights: bool = False
    # LSM's robust weighting (Tukey's biweight, lsm.py) against the samples of another surface in the
    # template: on in dense matching's refinement (dense/refine.py); docs/validation.md#dense-robust-lsm
    robust: bool = False

    @property
    def widest(self):
        return max(self.template, self.wide_template)

    @property
    def tukey(self):
        return TUKEY_C if self.robust else 0.0

    def check(self):
        super().check()
        if self.step < 1 or self.tile < 4 * self.step:
            raise InputError(f"STEP must be >= 1 and the tile at least 4 STEP, got step {self.step}, tile {self.tile}")
        if not 0.0 <= self.psf_sigma <= 5.0:
            raise InputError(f"psf_sigma must lie between 0 (off) and 5 px, got {self.psf_sigma}")
        if self.wide_template and (self.wide_template % 2 == 0 or self.wide_template <= self.template):
            raise InputError(
                f"the wide template must be 0 (off) or an odd size larger than the template "
                f"({self.template} px), got {self.wide_template}"
            )
        if self.reseed_cell and self.reseed_cell < 3:
            raise InputError(f"the reseed cell must be 0 (off) or at least 3 pixels, got {self.reseed_cell}")
        if self.psf not in ("sensor", "pixel", "off"):
            raise InputError(f"psf must be 'sensor', 'pixel' or 'off', got {self.psf!r}")
        return self
