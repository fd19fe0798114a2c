"""Gap filling of a per-cell DEM, always flagged in a mask raster.

Model: GDAL's FillNodata (GDALFillNodata): each gap cell within `max_distance` cells of measured ones gets the
inverse-distance weighted mean of the nearest measured cell found in each of the four quadrant directions
(no smoothing passes); farther cells stay gaps. The mask raster (Byte, the DEM's grid) says what each cell
is: 0 measured (the per-cell median of its points), 1 filled, 255 still a gap. Both rasters are read and
written in strips of rows, and FillNodata works by scanlines, so memory follows the DEM's width, not its
area. The DEM's overviews are rebuilt.

studies/dense_fusion.py measures interpolation against the dense points a cell without refined ones has.

Failure modes: CancelledError through the feedback (the caller's atomic outputs then leave nothing).

Reference: GDAL, gdal_fillnodata (alg/rasterfill.cpp)."""
import numpy as np

from .. import progress
from ..atomic import closing
from ..errors import CancelledError
from .geotiff import overview_levels

MEASURED, FILLED, GAP = 0, 1, 255
STRIP = 512         # rows read at a time


def _strips(rows):
    return [(r, min(STRIP, rows - r)) for r in range(0, rows, STRIP)]


def fill_gaps(path, mask_path, max_distance, feedback=None):
    """Fill the gaps of the single-band GeoTIFF `path` (in place) within `max_distance` cells and write the
    mask raster `mask_path` (module docstring). Returns the number of cells filled."""
    from osgeo import gdal
    gdal.UseExceptions()
    with closing(gdal.Open(str(path), gdal.GA_Update)) as ds:
        band = ds.GetRasterBand(1)
        cols, rows = ds.RasterXSize, ds.RasterYSize
        driver = gdal.GetDriverByName("GTiff")
        with closing(driver.Create(str(mask_path), cols, rows, 1, gdal.GDT_Byte,
                                   ["TILED=YES", "COMPRESS=DEFLATE"])) as mask:
            mask.SetGeoTransform(ds.GetGeoTransform())
            mask.SetProjection(ds.GetProjection())
            out = mask.GetRasterBand(1)
            out.SetNoDataValue(GAP)
            out.SetDescription("0 measured, 1 filled, 255 gap")
            for r, n in _strips(rows):
                valid = band.GetMaskBand().ReadAsArray(0, r, cols, n) > 0
                out.WriteArray(np.where(valid, MEASURED, GAP).astype(np.uint8), 0, r)
            progress.step(feedback, 10)
            try:
                gdal.FillNodata(band, None, float(max_distance), 0,
                                callback=progress.gdal_callback(progress.scaled(feedback, 10, 80)))
            except RuntimeError:
                if feedback is not None and feedback.isCanceled():
                    raise CancelledError("cancelled by the user") from None
                raise
            filled = 0
            for r, n in _strips(rows):
                valid = band.GetMaskBand().ReadAsArray(0, r, cols, n) > 0
                flags = out.ReadAsArray(0, r, cols, n)
                new = valid & (flags == GAP)
                filled += int(new.sum())
                flags[new] = FILLED
                out.WriteArray(flags, 0, r)
        levels = overview_levels((rows, cols))
        if levels:
            ds.BuildOverviews("AVERAGE", levels, callback=progress.gdal_callback(progress.scaled(feedback, 80, 100)))
    return filled
