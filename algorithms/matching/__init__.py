"""Dense matching: least-squares matching (lsm), normalised cross-correlation (ncc), interest
points, region growing after Otto & Chau, three-image combinations and tie
point selection. Image coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel,
pixel (i, j) of an array has its centre at (j + 0.5, i + 0.5)."""
