"""The engine of interactive control-point measurement (issue 6): the state and edits of a measurement
session (session, with its undoable edits in edits), single edits of the block's points and
measurements (store), the residuals of the last adjustment kept in the block (residual_store),
predicted image positions and ground points of clicks (prediction), least-squares transfer of a
clicked point into the other images (transfer) and QGIS Georeferencer .points files (georeferencer).
Image coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel."""
