"""The engine of interactive control-point measurement (issue 6): the residuals of the last adjustment
as the block keeps them (residuals; stored, like the single edits of the points, through block.Block),
predicted image positions and ground points of clicks (prediction), least-squares transfer of a
clicked point into the other images (transfer) and QGIS Georeferencer .points files (georeferencer).
Image coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel."""
