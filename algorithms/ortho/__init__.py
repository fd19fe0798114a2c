"""Orthorectification by the indirect method (Hofmann et al., section 4.1): output grid, coarse-grid
ground -> image mapping with a stated error bound, resampling, occlusion, tiled GeoTIFF output."""
from .grid import OutputGrid, default_grid
from .orthorectify import OrthoResult, load_dem, orthorectify

__all__ = ["OutputGrid", "default_grid", "OrthoResult", "load_dem", "orthorectify"]
