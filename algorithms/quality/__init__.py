"""Accuracy assessment (methods.md section 7; K 3.6-3.7, Z 4): height differences of object points
and DEM cells against a reference DTM/DSM, their statistics per point group, class and slope,
figures and one self-contained HTML report."""
