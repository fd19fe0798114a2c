"""Dense per-pixel matching: epipolar resampling grids per tile, census cost with semi-global
aggregation, sub-pixel refinement in the original images, triangulation and fusion."""
