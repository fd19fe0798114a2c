"""Matching parameters with the papers' defaults (methods.md section 3; paper 003 section 2,
paper 000 section 3.3)."""
from dataclasses import dataclass

from ..errors import InputError


@dataclass
class LsmParams:
    """Least-squares matching: window and the acceptance criteria of a matched point."""

    template: int = 19          # window size, px (odd)
    max_iterations: int = 10    # iterations < maximum
    convergence: float = 0.01   # px: stop when the position update is smaller
    rho_min: float = 0.6        # correlation coefficient > rho_min (0.7 in K for DEM points)
    # px: semi-major axis of the error ellipse < threshold. H/K's 0.1 px; on the simulated SPOT 5
    # triplet (8 bit, noise 1 DN) the ellipses are 1.7-2.2x optimistic (the residuals are aliasing
    # and sub-template relief, not noise: the same with noise 0) and 0.1 px is the binding
    # criterion (60 % of textured nodes); 0.15 px gives 79 % but fills 29 % of the uniform grass
    # and raises the field RMS 0.21 -> 0.24 px, so the paper's value stays
    max_ellipse: float = 0.1
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

    step: int = 10              # px between a point and its four neighbours (10-15 in H)
    tile: int = 1024            # px, square tiles of the reference image, grown independently
    # neighbours' initial affine shape: the sensor models' local affine of the tile (True), or the
    # popped point's estimate as in H (False), which drifted along growth paths in the simulated
    # triplet (a5 up to 1.48 where ~1 is right; 0.49 px RMS vs 0.24 px on crops)
    model_affine: bool = True
    # resolution adaptation (K 3.3: "different image scales (HRS 10 x 5 m, HRG) are adapted by
    # scale factors"): the finer image is low-passed to the coarser one's footprint through the
    # models' local affine A (region_growing.adapt_resolution). psf selects the PSF model:
    #   "sensor": each instrument's own PSF (region_growing.SENSOR_PSF: detector box, detector_lines
    #             along track, 1 line of motion smear, Gaussian optics) as Gaussian-equivalent
    #             variances; the finer image gets the difference of variances per axis. Images
    #             whose PSF is unknown (RPC, unlisted instruments) fall back to "pixel";
    #   "pixel":  both PSFs Gaussian of psf_sigma px of each image's own pixels (square
    #             detectors); 0.5 px is SPOT's MTF(Nyquist) ~ 0.3;
    #   "off":    no adaptation (as psf_sigma 0 in "pixel").
    # Measured on the 3 km triplet, HRG -> HRS1: see tests/algorithms/test_region_growing.py
    psf: str = "sensor"
    psf_sigma: float = 0.5
    # second, wider window (odd px; 0 = off) for a node whose LSM at `template` fails inside the
    # images (mostly the error ellipse or convergence on weak or striped texture): a larger window
    # lowers the noise part of the precision at the price of more relief inside it (the
    # Kanade-Okutomi trade, one step); the point must still pass every criterion. Off by default:
    # 27 raises the coverage of textured ground on the 3 km triplet from 68.5 to 93.1 %, but the
    # added points are worse than the ellipse says (fields 0.24 px RMS, 3x their ellipses), the lake
    # of the 12 km scene fills (76 points/km2, 14 % beyond 5 m) and the Ventoux DSM's NMAD rises
    # 9.9 -> 10.8 m (tests/algorithms/test_region_growing.py, test_end_to_end.py)
    wide_template: int = 0
    # px of image 1: where automatic seeds are used, a second round of them, one interest point per
    # cell at the lattice nodes the first round's growth did not try (region_growing.py's
    # docstring); 0 = one round
    reseed_cell: int = 16
    # the MPGC refinement of the group 3 points with support weights (refinement.py's SUPPORT_CENTRE,
    # SUPPORT_SIMILARITY), which make each match measure the surface around its template centre:
    # on the 12 km simulated triplet the three-ray heights on textured open ground 2.70 -> 2.26 m
    # RMS (test_end_to_end.py; on in the DEM pipeline model). Off by default: the positions are then
    # no longer those a uniform window finds, and the Pleiades triplet's forward-backward check
    # against pairwise LSM (uniform windows) rises 0.070 / 0.065 / 0.116 -> 0.127 / 0.117 / 0.199 px
    # (tests/real/test_matching_pleiades.py), while its tie points' sigma_0 falls 0.086 -> 0.067
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
