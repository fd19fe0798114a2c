"""Accuracy assessment (Kornus et al. 2006, section 3.6-3.7, Zhang and Gruen 2004, section 4): height
differences of object points and DEM cells against a reference DTM/DSM, their statistics per point group, class
and slope, figures and one self-contained HTML report."""
