"""The engine of interactive control-point measurement: the state and edits of a measurement session
(session, with its undoable edits in edits; stored through block.Block), predicted image positions
and ground points of clicks (prediction), least-squares transfer of a clicked point into the other
images (transfer) and QGIS Georeferencer .points files (georeferencer).
Image coordinates are GDAL's: (0, 0) is the top-left corner of the first pixel."""
