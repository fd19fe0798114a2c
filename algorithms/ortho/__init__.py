"""Orthorectification by the indirect method (Heipke et al. 1992, section 4.1): output grid, coarse-grid
ground -> image mapping with a stated error bound, resampling, occlusion, tiled GeoTIFF output."""

from .grid import OutputGrid, default_grid
from .orthorectify import OrthoOutputs, OrthoResult, OrthoSettings, orthorectify

__all__ = ["OutputGrid", "default_grid", "OrthoOutputs", "OrthoResult", "OrthoSettings", "orthorectify"]
