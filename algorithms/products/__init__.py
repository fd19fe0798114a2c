"""DEM products made from DSMs: merges of several (merge_dems) and terrain models (extract_dtm). They build on the
surface rasters (surface/) and the co-registration (quality/), which neither imports."""
